"""The selected object's pictures, as napari layers beside its Labels layer.

The SDF (blue inside, red outside), the pushed-forward disk and the reporter's disk are 2-D Image
layers to the right of the labels, each with its colour bar beside it (numbers at its ends);
the outline and the skeleton are a Shapes layer of paths; a Points layer holds the captions.
A 3-D object gets its shells as maps and its surface (napari's 3-D view shows it). The layers
are updated in place when the selection or the frame changes; no layer adds a slider.

:class:`PictureView` makes the pictures in a worker and shows only those of the object selected
*now*: every selection supersedes the earlier ones, cached or not.
"""

from __future__ import annotations

from collections import OrderedDict

import numpy as np
from napari.layers import Image, Points, Shapes, Surface
from napari.qt.threading import thread_worker
from qtpy.QtCore import QTimer

from ..analysis.pictures import ObjectPictures, VolumePictures, object_pictures
from ._model import PICTURE_SUFFIXES, Analysis, layer_shape, picture_names

#: Side of a picture cell as a fraction of the labels' height, and the gap between cells.
CELL, GAP = 0.45, 0.3
SIZE = 128
#: Each picture's colour bar: columns of the picture array right of the picture (the same
#: colour map and limits), after a gap of this many columns.
BAR, BAR_GAP = 8, 4
#: Pictures of this many objects are kept.
CACHE = 64
SKELETON, OUTLINE = "#ffd000", "#202020"
#: The midline (anterior end first) and its cross-sections (one per profile bin).
MIDLINE, SECTIONS = "#00e5ff", "#7fd8e6"
#: Points of the captions layer: five texts, the two ends of three colour bars, two lines on
#: the disk's folded samples, and two points without text at the corners of them all (the view
#: made to fit the layers then holds the texts too).
SLOTS = 15
#: Height of a caption's letters as a fraction of a picture cell's side. The captions are
#: sized in the pictures' own (world) units, like the pictures: whatever the zoom, they keep
#: their places beside them and never run into them or into each other. napari writes a
#: caption above and right of its point (the point is its text's lower left corner).
TEXT = 0.08
#: Lines of captions (in letter heights): from one line's foot to the next; the foot of a line
#: over a picture above its top edge (room for descenders); the foot of the first line under a
#: picture below its bottom edge (room for the line and its ascenders).
LINE, GAP_ABOVE, BELOW = 1.5, 0.5, 1.9
#: napari's text size that gives letters one world unit high (its sizes are points, 1/72 in,
#: at 96 dots per inch).
POINTS_PER_UNIT = 0.75


def _cells(layer) -> dict[str, tuple[float, float, float]]:
    """World (top, left, side) of the picture cells right of the labels (last two axes)."""
    ny, nx = layer_shape(layer)[-2:]
    sy, sx = layer.scale[-2:]
    ty, tx = layer.translate[-2:]
    side = CELL * ny * sy
    left, top, step = tx + nx * sx + GAP * side, ty + 0.25 * side, side * (1 + 2 * GAP)
    return {"sdf": (top, left, side), "disk": (top, left + step, side),
            "intensity_disk": (top + step, left, side), "shells": (top, left, side)}


def _layer(viewer, name: str, kind, make):
    """The viewer's layer ``name`` of class ``kind``, made by ``make()`` when missing.

    The layers the user selected stay selected, and no one is told of the new layer's passing
    selection (napari selects a layer it adds): a plotter that follows the selection would
    otherwise start plotting a picture layer, and hear of its every change."""
    if name in viewer.layers and isinstance(viewer.layers[name], kind):
        return viewer.layers[name]
    selection = viewer.layers.selection
    chosen, active = set(selection), selection.active
    with selection.events.blocker_all():
        layer = make()
        selection.active = None
        selection.update(chosen)
        if active is not None:
            selection.active = active
    return layer


def _set(obj, **values) -> None:
    """Set the attributes that differ: each napari setter refreshes its layer."""
    for key, value in values.items():
        old = getattr(obj, key)
        if not np.array_equal(np.asarray(old, dtype=object), np.asarray(value, dtype=object)):
            setattr(obj, key, value)


def with_bar(data: np.ndarray, limits: tuple[float, float], fill: float) -> np.ndarray:
    """``data`` with its colour bar on the right: :data:`BAR_GAP` columns of ``fill``, then
    :data:`BAR` columns running from ``limits[1]`` (top) to ``limits[0]`` (bottom).

    >>> with_bar(np.zeros((3, 3)), (-1.0, 1.0), 0.0)[:, -1].tolist()
    [1.0, 0.0, -1.0]
    """
    n = data.shape[0]
    bar = np.repeat(np.linspace(limits[1], limits[0], n)[:, None], BAR, axis=1)
    return np.hstack([data, np.full((n, BAR_GAP), fill), bar])


def _image(viewer, name, data, cell, colormap, limits, nan=0.0):
    """The picture ``data`` in ``cell``, its colour bar on its right (napari's own colour bars
    would all stack in one corner of the canvas, none saying whose it is)."""
    top, left, side = cell
    step = side / max(data.shape)  # square pixels; the longer side fills the cell
    data = with_bar(np.nan_to_num(data, nan=nan), limits, nan)  # the bar right of the cell
    scale = (step, step)
    layer = _layer(viewer, name, Image, lambda: viewer.add_image(
        data, name=name, colormap=colormap, contrast_limits=limits, scale=scale,
        translate=(top, left), interpolation2d="nearest"))
    layer.data = data
    if layer.colormap.name != colormap:  # (a blank picture made first may have another)
        layer.colormap = colormap
    _set(layer, scale=scale, translate=(top, left), contrast_limits=limits, visible=True,
         opacity=1.0)
    _set(layer.colorbar, visible=False)
    return layer


def _symmetric(a: np.ndarray) -> tuple[float, float]:
    m = float(np.nanmax(np.abs(a))) if np.isfinite(a).any() else 1.0
    return -max(m, 1e-6), max(m, 1e-6)


def sdf_limits(sdf: np.ndarray) -> tuple[float, float]:
    """The SDF picture's colour range: ± the object's depth (its most negative value), so that
    the object's inside spans the colours; the far corners outside, which can lie many times
    farther, saturate red.

    >>> sdf_limits(np.array([[-2.0, 0.5], [30.0, 1.0]]))
    (-2.0, 2.0)
    """
    inside = sdf[np.isfinite(sdf) & (sdf < 0)]
    return _symmetric(inside) if inside.size else _symmetric(sdf)


def number(value: float) -> str:
    """A colour bar's end value, short: whole above 100, three significant digits below.

    >>> number(1388.48), number(-27.74), number(0.5231), number(-0.000123)
    ('1388', '-27.7', '0.523', '-0.000123')
    """
    return f"{value:.0f}" if abs(value) >= 100 else f"{value:.3g}"


def _bar_ends(cell, limits, rows: int = SIZE, height: float = 1.0) -> tuple[list, list]:
    """Where the numbers at the two ends of a cell's colour bar go (over its top, a line under
    the cell's title, and under its bottom), and their texts. ``rows``: the picture's longer
    side in pixels; ``height``: the picture's height over its longer side."""
    top, left, side = cell
    x = left + side * (1 + BAR_GAP / rows)  # the bar's left edge
    return ([_above(cell, x), (top + height * side + BELOW * TEXT * side, x)],
            [number(limits[1]), number(limits[0])])


def _restyle(viewer, source: str, keys, **props) -> None:
    """Set ``props`` (e.g. ``visible=False``) on those of the pictures ``keys`` that exist."""
    for key in keys:
        name = picture_names(source)[key]
        if name in viewer.layers:
            _set(viewer.layers[name], **props)


def caption(viewer, layer, where: list, texts: list[str], side: float) -> None:
    """Texts centred on world points ``where``: (y, x) beside a 2-D object's pictures,
    (z, y, x) for a 3-D object's (so that napari's 3-D view shows them in space).

    The layer always holds :data:`SLOTS` points (unused ones at the first point, with no
    text): a new caption then changes only napari's texts, where a new number of points would
    make napari rebuild the layer's points and texts. The texts are the layer's text array, not
    its ``features``: a features table would be offered to plotters as a column of words, and
    rewritten at every selection."""
    name = picture_names(layer.name)["captions"]
    data = np.asarray(where, float)
    data = data.reshape(-1, data.shape[-1])
    data = np.concatenate([data, np.repeat(data[:1], SLOTS - len(data), axis=0)])
    texts = list(texts) + [""] * (SLOTS - len(texts))
    size = TEXT * side * POINTS_PER_UNIT  # letters TEXT × side high, at any zoom
    if name in viewer.layers and viewer.layers[name].ndim != data.shape[1]:
        viewer.layers.remove(name)  # the layer was analysed with another first axis
    pts = _layer(viewer, name, Points, lambda: viewer.add_points(
        data, name=name, size=0.01, face_color="transparent", border_color="transparent",
        text={"string": texts, "color": "white", "size": size, "scaling": True,
              "anchor": "upper_left"}))
    if not np.array_equal(pts.data, data):
        pts.data = data
    if caption_texts(pts) != texts:
        pts.text.string = texts
    _set(pts.text, size=size)
    _set(pts, visible=True)
    top = len(viewer.layers) - 1
    if viewer.layers.index(pts) != top:  # over the pictures
        viewer.layers.move(viewer.layers.index(pts), top + 1)


def caption_texts(captions) -> list[str]:
    """The texts a captions layer shows (its unused slots as "")."""
    return [str(t) for t in captions.text.values]


def _above(cell, x: float | None = None, lines: int = 1) -> tuple[float, float]:
    """Where a caption ``lines`` lines over a cell goes (its text's lower left corner), at the
    cell's left edge or at ``x``."""
    top, left, side = cell
    return top - (GAP_ABOVE + LINE * (lines - 1)) * TEXT * side, left if x is None else x


def show(viewer, layer, analysis: Analysis, pictures) -> None:
    """Show ``pictures`` (of the selected object) beside ``layer``."""
    if isinstance(pictures, VolumePictures):
        _show_3d(viewer, layer, analysis, pictures)
    else:
        _show_2d(viewer, layer, analysis, pictures)


def _show_2d(viewer, layer, analysis: Analysis, p: ObjectPictures) -> None:
    n = picture_names(layer.name)
    cells = _cells(layer)
    limits = {"sdf": sdf_limits(p.sdf), "disk": _symmetric(p.disk)}
    _image(viewer, n["sdf"], p.sdf, cells["sdf"], "bwr", limits["sdf"])
    _image(viewer, n["disk"], p.disk, cells["disk"], "bwr", limits["disk"])
    if p.intensity_disk is not None:
        hi = float(np.nanmax(p.intensity_disk)) if np.isfinite(p.intensity_disk).any() else 1
        limits["intensity_disk"] = (0.0, max(hi, 1e-6))
        _image(viewer, n["intensity_disk"], p.intensity_disk, cells["intensity_disk"],
               "magma", limits["intensity_disk"])
    else:
        _restyle(viewer, layer.name, ["intensity_disk"], visible=False)
    scale, shift = np.asarray(layer.scale[-2:]), np.asarray(layer.translate[-2:])
    top, left, side = cells["sdf"]
    on_sdf = [(np.asarray(q) - p.sdf_corner) / p.sdf_step * side / SIZE + (top, left)
              for q in [p.outline, *p.skeleton_image]]
    top2, left2, side2 = cells["disk"]
    on_disk = [np.asarray(q) * side2 / SIZE + (top2, left2) for q in p.skeleton_disk]
    on_object = [np.asarray(q) * scale + shift for q in p.skeleton_image]
    paths = on_sdf + on_disk + on_object
    colors = [OUTLINE] + [SKELETON] * (len(paths) - 1)
    if p.midline is not None:  # the object's own axis, on the object and on its SDF
        axis = [p.midline.points, *p.midline.cross_sections()]
        paths += [np.asarray(q) * scale + shift for q in axis]
        paths += [(np.asarray(q) - p.sdf_corner) / p.sdf_step * side / SIZE + (top, left)
                  for q in axis]
        colors += ([MIDLINE] + [SECTIONS] * (len(axis) - 1)) * 2
    name = n["lines"]
    width = 0.004 * layer_shape(layer)[-2] * layer.scale[-2]
    lines = _layer(viewer, name, Shapes, lambda: viewer.add_shapes(
        name=name, ndim=2, edge_width=width, face_color="transparent"))
    lines.data = []
    if paths:
        lines.add_paths(paths, edge_color=colors, edge_width=width)
    _set(lines, visible=True, opacity=1.0)
    where = f"frame {p.frame} · " if analysis.time_lapse else ""
    axis = [f"midline (cyan) {p.midline.length:.0f} px"] if p.midline is not None else []
    texts = ["SDF (px)", "PF-SDF disk", f"{where}label {p.label}",
             "reporter (× mean)" if p.intensity_disk is not None else "",
             "; ".join(axis + p.notes), "", ""]
    spots = _spots_2d(layer)
    for key, lim in limits.items():
        ends, numbers = _bar_ends(cells[key], lim)
        spots += ends
        texts += numbers
    top, left, side = cells["disk"]
    folded = folded_words(analysis, p)  # under the disk's bottom number
    spots += [(top + side + (BELOW + LINE * k) * TEXT * side, left) for k in (1, 2)]
    texts += folded or ["", ""]
    caption(viewer, layer, spots, texts, side)


def folded_words(analysis: Analysis, p: ObjectPictures) -> list[str]:
    """Two lines under the PF-SDF disk saying what its red samples are, when it has any: the
    map folded them outside the object (the row's ``folded_fraction``); [] when none."""
    if not np.any(np.nan_to_num(p.disk) > 0):
        return []
    i = analysis.row_of(p.frame, p.label)
    share = float(analysis.table["folded_fraction"].iloc[i]) \
        if i is not None and "folded_fraction" in analysis.table else float(
            np.mean(p.disk[np.isfinite(p.disk)] > 0))
    return [f"red: {100 * share:.1f} % of the samples lie", "outside the object (map folded)"]


def _spots_2d(layer) -> list[tuple[float, float]]:
    """Where a 2-D object's captions go (each text runs right and up from its spot): over the
    SDF, over the disk, over both (the object), over the reporter's disk (each a line over the
    numbers at the top of their colour bars), and under the reporter's disk (notes: its place
    whether or not there is a reporter, clear of the disk's words); and two points with no text
    at the far corners of them all, so that napari's fit of the view holds every caption."""
    cells = _cells(layer)
    top, left, side = cells["sdf"]
    rtop, rleft, rside = cells["intensity_disk"]
    return [_above(cells["sdf"], lines=2), _above(cells["disk"], lines=2),
            _above(cells["sdf"], lines=3), _above(cells["intensity_disk"], lines=2),
            (rtop + rside + (BELOW + LINE) * TEXT * rside, rleft),
            (top + 2.7 * side, left + 3.4 * side), (top - 5.0 * TEXT * side, left)]


def _show_3d(viewer, layer, analysis: Analysis, p: VolumePictures) -> None:
    n = picture_names(layer.name)
    cells = _cells(layer)
    stacked = np.concatenate([s - np.nanmean(s) for s in p.shells], axis=0)
    top, left, side = cells["shells"]
    limits = _symmetric(stacked)
    _image(viewer, n["shells"], stacked, (top, left, side * 2), "bwr", limits)
    verts, faces, values = p.surface
    scale = np.asarray(layer.scale[-3:])
    shift = np.asarray(layer.translate[-3:])
    data = (verts * scale + shift, faces, values)
    name = n["surface"]
    surf = _layer(viewer, name, Surface, lambda: viewer.add_surface(
        data, name=name, colormap="viridis"))
    surf.data = data
    _set(surf, contrast_limits=(float(values.min()),
                                float(max(values.max(), values.min() + 1e-6))), visible=True,
         opacity=1.0)
    where = f"frame {p.frame} · " if analysis.time_lapse else ""
    z = float(shift[0] + scale[0] * (layer_shape(layer)[-3] - 1) / 2)  # mid-stack
    above = data[0][np.argmin(data[0][:, 1])] - (0, 0.08 * side, 0)  # over the surface
    rows = max(stacked.shape)
    ends, numbers = _bar_ends((top, left, side * 2), limits, rows, stacked.shape[0] / rows)
    caption(viewer, layer, [(z, *_above((top, left, side))),
                            (z, *_above((top + 2.25 * side, left, side))), above,
                            *[(z, *e) for e in ends]],
            [f"{where}label {p.label}: 4 shells (SDF − shell mean)", "surface: 3-D view",
             f"{where}label {p.label}", *numbers], side)


#: The pictures' layers, by their key in :func:`~._model.picture_names`.
PICTURES = [key for key in PICTURE_SUFFIXES if key != "captions"]
#: Opacity of the pictures shown while the selection's own are being made.
DIMMED = 0.25
#: Milliseconds after a first request before its blank picture layers are made: the worker
#: making the pictures starts first (napari hands it to its thread pool a millisecond later).
PLACEHOLDERS_MS = 5


def say(viewer, layer, text: str, analysis: Analysis | None = None,
        hide: bool = True) -> None:
    """No pictures for the selection: hide them (or, with ``hide=False``, dim them while the
    selection's own are being made) and say why where they would be."""
    _restyle(viewer, layer.name, PICTURES, **({"visible": False} if hide else
                                                {"opacity": DIMMED}))
    spots = _spots_2d(layer)  # the 2-D captions' places: only their texts change
    if analysis is not None and analysis.ndim == 3:
        spots = [(float(layer.translate[-3] + layer.scale[-3] * (layer_shape(layer)[-3] - 1) / 2),
                  *spots[0])]
    caption(viewer, layer, spots, [text], _cells(layer)["sdf"][2])


@thread_worker(start_thread=False)
def _make(analysis: Analysis, frame: int, label: int):
    t = frame if analysis.time_lapse else 0
    return object_pictures(analysis.labels, analysis.intensity, t, label,
                           params=analysis.params, axes=analysis.axes,
                           spacing=analysis.spacing, box=analysis.boxes.get((t, label)),
                           size=SIZE, midline=True)


class PictureView:
    """Shows the pictures of the selected object of one viewer; made in a worker, kept in a
    small cache; only the pictures of the selection made last are ever shown."""

    def __init__(self, viewer) -> None:
        self.viewer = viewer
        self.cache: OrderedDict = OrderedDict()
        self.wanted: tuple | None = None  # (layer, analysis, key)
        self.shown: tuple | None = None  # key of the pictures on screen
        self.worker = None

    def want(self, layer, analysis: Analysis) -> None:
        """Show the pictures of ``analysis.selection`` (made now or in the background)."""
        if analysis.selection is None:
            return
        frame, label = analysis.selection
        key = (analysis.key, frame, label)
        self.wanted = (layer, analysis, key)
        error = analysis.error_of(frame, label)
        where = f"frame {frame}, " if analysis.time_lapse else ""
        if label == 0 and analysis.selected_object is None:
            self._say("no object selected (the background)", key)
        elif error is None and label == 0 and analysis.time_lapse:
            self._say(f"object {analysis.selected_object} (track) is not in frame {frame}", key)
        elif error is None:
            self._say(f"{where}label {label}: not in this frame, no pictures", key)
        elif error:  # its first sentence: the rest is in the error column
            self._say(f"{where}label {label} has no features: {error.split(': ')[0]}", key)
        elif key in self.cache:
            self._show(key)
            if self.worker is None:
                self._prefetch()
        else:
            if self.worker is None:
                self._start()
            say(self.viewer, layer, f"making the pictures of {where}label {label}…", analysis,
                hide=False)
            if analysis.ndim == 2 and picture_names(layer.name)["disk"] not in self.viewer.layers:
                # the first pictures: napari makes their layers while the worker makes them
                QTimer.singleShot(PLACEHOLDERS_MS, lambda: self._placeholders(layer, analysis))

    def _placeholders(self, layer, analysis: Analysis) -> None:
        """Blank, dimmed picture layers, made while the first pictures are being made (napari
        builds a layer of a new kind once: then, not when the pictures come)."""
        if layer not in self.viewer.layers or self.wanted is None \
                or isinstance(self.cache.get(self.wanted[2]), ObjectPictures):
            return
        n, cells = picture_names(layer.name), _cells(layer)
        blank = np.zeros((SIZE, SIZE), np.float32)
        keys = ["sdf", "disk"] + (["intensity_disk"] if analysis.intensity is not None else [])
        for key in keys:
            if n[key] not in self.viewer.layers:
                _image(self.viewer, n[key], blank, cells[key],
                       "magma" if key == "intensity_disk" else "bwr", (-1.0, 1.0))
        _layer(self.viewer, n["lines"], Shapes, lambda: self.viewer.add_shapes(
            name=n["lines"], ndim=2, face_color="transparent"))
        _restyle(self.viewer, layer.name, PICTURES, opacity=DIMMED)
        self.viewer.reset_view()  # room for the pictures beside the image, once

    def _say(self, text: str, key) -> None:
        say(self.viewer, self.wanted[0], text, self.wanted[1])
        self.shown = key

    def _start(self, key=None) -> None:
        layer, analysis, wanted = self.wanted
        key = key or wanted
        self.worker = worker = _make(analysis, key[1], key[2])
        worker.returned.connect(lambda pics, key=key: self._done(key, pics))
        worker.errored.connect(lambda err, key=key: self._done(key, err))
        worker.finished.connect(self._finished)
        worker.start()

    def _done(self, key, result) -> None:
        self.cache[key] = result
        while len(self.cache) > CACHE:
            self.cache.popitem(last=False)
        if self.wanted is not None and self.wanted[2] == key:
            self._show(key)

    def _finished(self) -> None:
        self.worker = None
        if self.wanted is None:
            return
        if self.wanted[2] not in self.cache and self.shown != self.wanted[2]:
            self._start()
        else:
            self._prefetch()

    def _prefetch(self) -> None:
        """Make the selected object's pictures in the next frame (then in the one before)
        while nothing is wanted: stepping through time then shows them at once."""
        layer, analysis, (run, frame, label) = self.wanted
        if not analysis.time_lapse or analysis.selected_object is None:
            return
        for t in (frame + 1, frame - 1):
            there = analysis.label_of(analysis.selected_object, t)
            key = (run, t, there)
            if there is not None and key not in self.cache and analysis.error_of(t, there) == "":
                self._start(key)
                return

    def _show(self, key) -> None:
        layer, analysis, _ = self.wanted
        result = self.cache[key]
        self.cache.move_to_end(key)
        if layer not in self.viewer.layers:
            return
        if isinstance(result, Exception):
            self._say(f"no pictures: {result}", key)
            return
        pictures = picture_names(layer.name)
        first = pictures["disk"] not in self.viewer.layers \
            and pictures["shells"] not in self.viewer.layers
        show(self.viewer, layer, analysis, result)
        self.shown = key
        if first:  # make room for the new pictures beside the image, once
            self.viewer.reset_view()

    def clear(self) -> None:
        """Forget every picture (a new run)."""
        self.cache.clear()
        self.shown = None

    def stop(self) -> None:
        """Want nothing more (the layer is gone, or the dock): a picture being made is
        dropped when it ends, and nothing is made after it."""
        self.wanted = None
        self.clear()
