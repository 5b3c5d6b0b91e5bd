"""What the midline columns cost ``measure``, and how close they come to closed forms.

Run from the repository root::

    .venv/bin/python benchmarks/midline.py
    .venv/bin/python benchmarks/midline.py --reps 7

Cost: ``pf.measure(labels, reporter)`` on the bundled montage
(``napari_pfsdm.data.gastruloids.make_timelapse_montage(seed=0)``, 12 frames, 72 objects of
~28 px) and on one bent capsule at radius 150 and 600 px, each timed in the same run with the
midline and without it (``midline_measures`` in ``analysis.features`` replaced by one returning NaN:
everything else is the same code); the calls take turns in ``--reps`` passes and each one's
fastest wall time is kept. The ratio is with / without.

Accuracy: ellipses (half-axes a, b, turned) and bent capsules (radius R, half-width w, opening
span): ``midline_length`` against 2a and R·span + 2w, ``width_max`` against 2b and 2w.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

import napari_pfsdm as pf
from napari_pfsdm.analysis import features
from napari_pfsdm.core.descriptor import pfsdm
from napari_pfsdm.core.midline import midline, midline_columns
from napari_pfsdm.data.gastruloids import make_timelapse_montage
from napari_pfsdm.data.shapes import bent_capsule_mask


def _without_midline(result, image=None, *, offset=(0.0, 0.0), bins=10, anterior="reporter"):
    return dict.fromkeys(midline_columns(bins, image is not None), np.nan)


def cost(reps: int) -> None:
    real = features.midline_measures
    cases = {"montage (72 objects)": make_timelapse_montage(seed=0)[:2]}
    for radius in (150.0, 600.0):
        mask = bent_capsule_mask(radius, half_width=0.35, span=2.0)
        cols = np.mgrid[:mask.shape[0], :mask.shape[1]][1]
        cases[f"capsule r={radius:g} ({int(mask.sum())} px)"] = (mask.astype(np.uint8),
                                                                  cols + 10.0)
    for name, (labels, reporter) in cases.items():
        best = {"with": np.inf, "without": np.inf}
        for _ in range(reps):
            for which in best:
                features.midline_measures = real if which == "with" else _without_midline
                t = time.perf_counter()
                pf.measure(labels, reporter)
                best[which] = min(best[which], time.perf_counter() - t)
        features.midline_measures = real
        print(f"{name}: with {best['with']:.3f} s, without {best['without']:.3f} s, "
              f"ratio {best['with'] / best['without']:.2f}")


def accuracy() -> None:
    for a, b, deg in ((60, 25, 0), (80, 30, 30), (200, 60, 15), (300, 220, 45)):
        n = 2 * a + 21
        yy, xx = np.mgrid[:n, :n] - n // 2
        th = np.radians(deg)
        u, v = xx * np.cos(th) - yy * np.sin(th), xx * np.sin(th) + yy * np.cos(th)
        m = midline(pfsdm((u / a) ** 2 + (v / b) ** 2 <= 1))
        print(f"ellipse a={a} b={b} at {deg}°: length − 2a {m.length - 2 * a:+.2f} px, "
              f"width_max − 2b {m.width_max - 2 * b:+.2f} px")
    for radius, half, span in ((60, 0.25, 2.0), (100, 0.3, 1.2), (150, 0.35, 2.0),
                               (600, 0.35, 2.0)):
        m = midline(pfsdm(bent_capsule_mask(radius, half_width=half, span=span)))
        length, width = radius * span + 2 * half * radius, 2 * half * radius
        print(f"capsule R={radius} w={half * radius:g} span={span}: length − (R·span + 2w) "
              f"{m.length - length:+.2f} px, width_max − 2w {m.width_max - width:+.2f} px")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--reps", type=int, default=5)
    args = parser.parse_args()
    accuracy()
    cost(args.reps)


if __name__ == "__main__":
    main()
