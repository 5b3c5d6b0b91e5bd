"""Result layers: add or replace them, and keep them linked to the selected object and frame."""

from __future__ import annotations

import numpy as np

from ._compute import AnalysisOutput

#: Layer-name suffixes, after the source Labels layer's name.
SUFFIXES = {
    "disk": "PF-SDF disk",
    "intensity_disk": "intensity disk",
    "disk_skeleton": "skeleton on disk",
    "skeleton": "skeleton",
    "sdf": "SDF",
}


def layer_names(source: str) -> dict[str, str]:
    """Names of the result layers of the Labels layer called ``source``."""
    return {key: f"{source} {suffix}" for key, suffix in SUFFIXES.items()}


def _shape(layer) -> tuple:
    """Full-resolution data shape (also for multiscale layers)."""
    if getattr(layer, "multiscale", False):
        return tuple(int(n) for n in layer.level_shapes[0])
    return tuple(layer.data.shape)


def frame_axis(viewer, labels_layer) -> int | None:
    """World axis of the frames (None for a 2-D Labels layer)."""
    if labels_layer.ndim != 3:
        return None
    return viewer.dims.ndim - 3


def current_frame(viewer, labels_layer) -> int:
    """Frame index that the time slider shows for ``labels_layer``."""
    ax = frame_axis(viewer, labels_layer)
    if ax is None:
        return 0
    world = viewer.dims.point[ax]
    t = (world - labels_layer.translate[0]) / labels_layer.scale[0]
    return int(np.clip(np.rint(t), 0, _shape(labels_layer)[0] - 1))


def go_to(viewer, labels_layer, output: AnalysisOutput, frame: int, label: int) -> None:
    """Move the time slider to ``frame`` and select ``label`` (disk stack follows)."""
    ax = frame_axis(viewer, labels_layer)
    if ax is not None:
        viewer.dims.set_point(ax, labels_layer.translate[0] + frame * labels_layer.scale[0])
    labels_layer.selected_label = int(label)
    show_object(viewer, output, label)


def show_object(viewer, output: AnalysisOutput, label: int) -> None:
    idx = output.object_index(label)
    if idx is not None and viewer.dims.ndim > (3 if output.time_lapse else 2):
        viewer.dims.set_point(0, idx)


def _window_translate(labels_layer, corner: tuple[int, int]) -> tuple:
    """World translate of an array whose pixel (0, 0) is the labels' pixel ``corner``."""
    t = list(labels_layer.translate)
    t[-2] += corner[0] * labels_layer.scale[-2]
    t[-1] += corner[1] * labels_layer.scale[-1]
    return tuple(t)


def _name_axes(viewer, labels_layer) -> None:
    """Call the slider axes 'object' and 'frame' when the dims are exactly ours."""
    names = ["object", "frame", "y", "x"] if labels_layer.ndim == 3 else ["object", "y", "x"]
    if viewer.dims.ndim == len(names):
        viewer.dims.axis_labels = names


def _disk_geometry(labels_layer, output: AnalysisOutput, slot: int):
    """Scale and translate that put a disk image beside the labels (slot 0, 1, ...)."""
    ny, nx = _shape(labels_layer)[-2:]
    sy, sx = labels_layer.scale[-2:]
    ty, tx = labels_layer.translate[-2:]
    size = output.disk.shape[-1]
    height = ny * sy
    s = height / size
    gap = 0.05 * height
    lead = output.disk.ndim - 2  # object (+ frame) axes
    scale = [1.0] * lead + [s, s]
    translate = [0.0] * lead + [ty, tx + nx * sx + gap + slot * (height + gap)]
    if output.time_lapse:
        scale[1], translate[1] = labels_layer.scale[0], labels_layer.translate[0]
    return scale, translate


def _replace(viewer, name: str, kind: str, data, **kwargs):
    """Replace the layer called ``name`` (same kind) or add it."""
    if name in viewer.layers:
        old = viewer.layers[name]
        same = type(old).__name__.lower() == kind and old.data.shape == data.shape
        if same:
            for key, value in kwargs.items():
                if key in ("scale", "translate", "colormap", "contrast_limits", "opacity",
                           "blending"):
                    setattr(old, key, value)
            old.data = data
            return old
        viewer.layers.remove(old)
    return getattr(viewer, f"add_{kind}")(data, name=name, **kwargs)


def _limits(a: np.ndarray) -> tuple[float, float]:
    """Contrast limits centred on 0 (diverging colormap), robust to a few extreme values."""
    finite = np.abs(a[np.isfinite(a)])
    if finite.size == 0:
        return (-1.0, 1.0)
    m = float(np.percentile(finite, 99.5)) or float(finite.max()) or 1.0
    return (-m, m)


def show_results_steps(viewer, labels_layer, output: AnalysisOutput) -> list:
    """The steps that add (or replace) the result layers of one run, one layer per step.

    Run them one per event-loop iteration (the widget does) so that the viewer redraws and takes
    clicks between two layers; or call :func:`show_results` to do all at once.
    """
    names = layer_names(labels_layer.name)
    scale, translate = _disk_geometry(labels_layer, output, 0)
    geo = {"scale": tuple(labels_layer.scale), "translate": tuple(labels_layer.translate)}
    label = labels_layer.selected_label
    if output.object_index(label) is None:
        label = int(output.object_labels[0])

    def features():
        table = output.table.copy()
        table.attrs = {}
        # napari's convention: an 'index' column says which label a row belongs to (its
        # status bar then shows one row per label, the last frame's; the 'frame' column says so)
        table.insert(0, "index", table["label"].to_numpy())
        labels_layer.features = table

    def disk():
        _replace(viewer, names["disk"], "image", output.disk, colormap="RdBu_r",
                 contrast_limits=_limits(output.disk), scale=scale, translate=translate)

    def disk_skeleton():
        _replace(viewer, names["disk_skeleton"], "labels", output.disk_skeleton, scale=scale,
                 translate=translate)

    def intensity_disk():
        if output.intensity_disk is None:
            if names["intensity_disk"] in viewer.layers:
                viewer.layers.remove(names["intensity_disk"])
            return
        scale2, translate2 = _disk_geometry(labels_layer, output, 1)
        finite = output.intensity_disk[np.isfinite(output.intensity_disk)]
        hi = float(finite.max()) if finite.size else 1.0
        lo = float(finite.min()) if finite.size else 0.0
        _replace(viewer, names["intensity_disk"], "image", output.intensity_disk,
                 colormap="magma", contrast_limits=(lo, hi if hi > lo else lo + 1),
                 scale=scale2, translate=translate2)

    def skeleton():
        _replace(viewer, names["skeleton"], "labels", output.skeleton, **geo)

    def sdf():
        window, corner = output.sdf_window(label)
        layer = _replace(viewer, names["sdf"], "image", window, colormap="RdBu_r",
                         contrast_limits=_limits(window), opacity=0.6, scale=geo["scale"],
                         translate=_window_translate(labels_layer, corner))
        layer.metadata["pfsdm_label"] = label

    def select():
        _name_axes(viewer, labels_layer)
        labels_layer.selected_label = label
        show_object(viewer, output, label)
        viewer.layers.selection.active = labels_layer

    return [features, disk, disk_skeleton, intensity_disk, skeleton, sdf, select]


def show_results(viewer, labels_layer, output: AnalysisOutput) -> list:
    """Add (or replace) the result layers of one run at once; return them."""
    for step in show_results_steps(viewer, labels_layer, output):
        step()
    return [viewer.layers[n] for n in layer_names(labels_layer.name).values()
            if n in viewer.layers]


def update_sdf(viewer, labels_layer, output: AnalysisOutput, label: int) -> None:
    """Show the SDF of ``label`` in the SDF layer (if that layer is still there)."""
    name = layer_names(labels_layer.name)["sdf"]
    if name not in viewer.layers or output.object_index(label) is None:
        return
    layer = viewer.layers[name]
    if layer.metadata.get("pfsdm_label") == label:
        return
    window, corner = output.sdf_window(label)
    layer.translate = _window_translate(labels_layer, corner)
    layer.data = window
    layer.contrast_limits = _limits(window)
    layer.metadata["pfsdm_label"] = label
