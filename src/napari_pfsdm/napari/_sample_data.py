"""Sample data for File ▸ Open Sample (generated deterministically, in well under two seconds)."""

from __future__ import annotations

import numpy as np


def gastruloid_timelapse() -> list[tuple]:
    """A synthetic gastruloid-like time-lapse: reporter intensity + labels, 6 objects, 12 frames.

    Some objects develop one body axis, others several; ``metadata["groups"]`` of the Labels layer
    maps each label to ``"single-axis"`` or ``"multi-axes"`` (the trajectory plot can colour by it).
    """
    from ..data.gastruloids import make_timelapse_montage

    labels, intensity, groups = make_timelapse_montage(n_objects=6, n_frames=12, size=256, seed=0)
    return [
        (intensity, {"name": "gastruloids reporter", "colormap": "magma"}, "image"),
        (labels, {"name": "gastruloids", "metadata": {"groups": dict(groups)}}, "labels"),
    ]


def benchmark_shapes() -> list[tuple]:
    """The five-shape benchmark set: 5 shapes × 4 random similarity transforms, one Labels image.

    Each object's label is its index + 1; ``metadata["groups"]`` maps labels to shape names.
    """
    from ..data.shapes import make_benchmark_set

    masks, classes, names = make_benchmark_set(n_per_class=4, perturb=False, seed=0, size=96)
    n = len(masks)
    n_cols = 5
    n_rows = int(np.ceil(n / n_cols))
    h, w = masks[0].shape
    labels = np.zeros((n_rows * h, n_cols * w), dtype=np.uint16)
    # class by class: put each class on one column so that similar shapes line up
    per_class = n // len(names)
    groups = {}
    for i, mask in enumerate(masks):
        c, r = divmod(i, per_class)
        labels[r * h:(r + 1) * h, c * w:(c + 1) * w][np.asarray(mask, bool)] = i + 1
        groups[i + 1] = str(names[int(classes[i])])
    return [(labels, {"name": "five shapes", "metadata": {"groups": groups}}, "labels")]
