"""A report to share: one self-contained HTML page of a run, readable offline in any browser.

:func:`report_html` turns a feature table (with its options record) into one HTML text, the
findings first: what differs between the groups (a test per measure, in physical units and
times, :mod:`napari_pfsdm.analysis.findings`) and how well the features predict the groups
(balanced accuracy, confusion matrix); then the trajectories per group in the PCA plane, a few
measures over time (each group's mean ± sd), what each of PC1 … PC3 means (the classic measure
it follows, its loadings as a ring × Fourier index map, the real objects at −2σ … +2σ) and a
gallery of the most extreme objects per PC; counts, methods and options last. Terms are glossed
where they first appear. Figures are inline PNGs (``data:image/png;base64``), the style is
inline CSS, there are no links out and no script: the file can be mailed, archived, and
opened offline. Every text that comes from the user (movie and group names, the title) is
HTML-escaped.

Headless: figures are drawn with :class:`matplotlib.figure.Figure` (no pyplot, no GUI
backend). Writing the file (atomically, never over a file napari-pfsdm did not write) is
:func:`napari_pfsdm.report.write_report`, the function the command line (``pfsdm report``) and
the napari plugin call: this module only builds the text, since the layers below the file
layer write no files (tests/test_layering.py).

Its length (about 650 lines) is the page's sections, each a small figure-and-words function
in page order, and the page's CSS and skeleton; they share one table and its derived PCA.
"""

from __future__ import annotations

import datetime
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
import pandas as pd

from .._version import __version__
from ..core.distances import check_elastic_weight
from ..core.params import DERIVED, WEIGHT_OPTIONS, option
from ..core.table_options import carry_options, table_options
from ..core.table_schema import NO_TRACK, TRACK_COLUMN
from ..errors import InputError
from .html_parts import GENERATOR
from .html_parts import escaped as _e
from .html_parts import figure as _figure
from .html_parts import image as _img
from .html_parts import table_html as _table_html
from .label_images import check_labels_match
from .physical import space_unit_of, time_label, time_unit_of, time_values
from .plot_text import plot_text

__all__ = ["GENERATOR", "REPORT_COLUMNS", "check_labels", "report_html"]

#: The measures drawn over time by default (those the table has).
REPORT_COLUMNS = ("area", "circularity", "solidity", "intensity_mean")
#: Objects per end of each PC in the gallery.
GALLERY = 3
#: Components explained, drawn and shown in the gallery.
N_PCS = 3
#: Objects whose nearest shapes the report shows (spread along PC1), and how many each.
NEAREST_QUERIES, NEAREST_SHOWN = 4, 5
#: At most this many objects' trajectories per panel (every k-th beyond).
MAX_LINES = 200
#: At most this many groups get a trajectory panel (the first, by name).
MAX_PANELS = 9

_MEANING_OF_DERIVED = {
    "weights": "quadrature weight of each ring in the distance (from the options)",
    "mode_weights": "weight of each Fourier index in the distance (from the options)",
    "ndim": "dimension of the objects (2: masks in images, 3: volumes)",
    "axes": "the axes of the labels (T: time, Z, Y, X)",
    "spacing": "pixel (voxel) size along each axis",
}

_CSS = """
body{font-family:system-ui,-apple-system,'Segoe UI',Helvetica,Arial,sans-serif;margin:0 auto;
max-width:1180px;padding:16px 24px;color:#222;line-height:1.4}
h1{font-size:1.6em;margin:.2em 0}h2{font-size:1.25em;border-bottom:2px solid #ddd;
margin-top:1.6em;padding-bottom:.2em}h3{font-size:1.05em;margin:1.1em 0 .3em}
table{border-collapse:collapse;font-size:.88em;margin:.4em 0}
td,th{border:1px solid #ddd;padding:3px 8px;text-align:left;vertical-align:top}
th{background:#f3f3f3}td.num{text-align:right;font-variant-numeric:tabular-nums}
img{max-width:100%;height:auto}.note{color:#555;font-size:.9em}
.toc a{margin-right:1em}.gallery{display:flex;flex-wrap:wrap;gap:10px;margin:.3em 0 1em}
figure{margin:0;text-align:center;font-size:.8em;color:#444}
figure img{border:1px solid #ddd;background:#fff}.row{margin:.2em 0 .6em}
.muted{color:#888}.end{writing-mode:vertical-rl;transform:rotate(180deg);
text-align:center;color:#555;font-size:.85em;margin-left:8px}
.gloss{color:#666;font-size:.92em}.row img,.row table{display:inline-block;vertical-align:top;
margin-right:14px}
"""


# ------------------------------------------------------------------------------- helpers
def _shown(value: Any, limit: int = 80) -> str:
    if isinstance(value, np.ndarray):
        value = value.tolist()
    if isinstance(value, float):
        return f"{value:g}"
    if isinstance(value, list | tuple):
        text = ", ".join(f"{v:.4g}" if isinstance(v, float) else str(v) for v in value)
        text = f"[{text}]"
    else:
        text = str(value)
    return text if len(text) <= limit else text[: limit - 2] + " …"


def _meaning(name: str) -> str:
    try:
        return option(name).help
    except KeyError:
        pass
    if name in _MEANING_OF_DERIVED:
        return _MEANING_OF_DERIVED[name]
    if name in DERIVED:
        return "derived from the options"
    return ""


def _group_names(table: pd.DataFrame) -> list[str]:
    if "group" not in table.columns:
        return []
    return sorted(set(table["group"].fillna("").astype(str)) - {""})


def _with_groups(table: pd.DataFrame, groups) -> pd.DataFrame:
    """The table with a ``group`` column ("" for an object without one).

    ``groups``: None (the table's own ``group`` column, if any), a mapping object → group (the
    object is the ``track_id`` of a linked table, else the ``label``; keys as numbers or
    text), or a groups table as :func:`~napari_pfsdm.analysis.reduction.read_groups` reads.
    """
    if groups is None:
        if "group" in table.columns:
            out = table.copy()
            out["group"] = out["group"].fillna("").astype(str)
            return carry_options(table, out)
        return table
    if isinstance(groups, pd.DataFrame):
        from .groups import attach_groups

        return attach_groups(table, groups)
    if not isinstance(groups, Mapping):
        raise InputError("groups must be a mapping object → group or a groups table")
    known = {str(k): str(v) for k, v in groups.items()}
    key = TRACK_COLUMN if TRACK_COLUMN in table.columns else "label"
    out = table.copy()
    out["group"] = [known.get(str(k), "") for k in table[key].to_numpy()]
    return carry_options(table, out)


def _colours(names: Sequence[str]) -> dict[str, Any]:
    from matplotlib import colormaps

    tab = colormaps["tab10"]
    return {n: tab(i % 10) for i, n in enumerate(names)}


def _wrapped(text: str, width: int) -> str:
    """``text`` on lines of at most ``width`` characters (a long movie name cut), at most
    three lines: a caption that stays under its picture."""
    import textwrap

    lines = textwrap.wrap(str(text), width, break_long_words=True) or [""]
    return "\n".join(lines[:3]) + (" …" if len(lines) > 3 else "")


def _where(row: Mapping[str, Any], several_movies: bool) -> str:
    text = f"frame {int(row['frame'])}, label {int(row['label'])}"
    if several_movies and "movie" in row:
        text = f"{row['movie']}: {text}"
    return text


# ------------------------------------------------------------------------------- outlines
class _Masks:
    """The mask of (movie, frame, label) from the label movie(s), or None."""

    def __init__(self, labels, table: pd.DataFrame, names=None):
        from ..core.table_schema import table_ndim

        self.labels = labels
        self.names = names  # the labels' files (one, or movie -> file), for messages
        self.movies = (sorted(set(table["movie"].astype(str))) if "movie" in table.columns
                       else [])
        self.ndim = table_ndim(table_options(table))  # 3: volumes, drawn projected along z

    def __bool__(self) -> bool:
        return self.labels is not None

    def check(self, table: pd.DataFrame) -> None:
        """Refuse, in plain words, label arrays that cannot be the table's segmentation."""
        if self.labels is None:
            return
        arrays = (self.labels.items() if isinstance(self.labels, Mapping)
                  else [("", self.labels)])
        for movie, arr in arrays:
            name = self.where(movie) + (" (the labels)" if self.names else "")
            dtype = np.dtype(getattr(arr, "dtype", np.asarray(arr).dtype))
            if dtype.kind not in "iub":  # signed, unsigned, boolean
                raise InputError(f"{name} hold {dtype} values, not whole numbers: give the "
                                 "segmentation (one whole number per object), not an image")
            ndim = getattr(arr, "ndim", 0)
            if ndim not in (self.ndim, self.ndim + 1):
                raise InputError(f"{name} have {ndim} axes; the table's objects need "
                                 f"{self.ndim} (one image) or {self.ndim + 1} (a movie)")
            rows = table[table["movie"].astype(str) == movie] if movie and "movie" in table \
                else table
            if ndim == self.ndim + 1 and len(rows) and int(rows["frame"].max()) >= arr.shape[0]:
                raise InputError(f"{name} have {arr.shape[0]} frames but the table has frame "
                                 f"{int(rows['frame'].max())}: give the label movie the table "
                                 "was measured from")
            if ndim == self.ndim and len(rows) and rows["frame"].nunique() > 1:
                raise InputError(f"{name} are one image but the table's objects are in "
                                 f"{rows['frame'].nunique()} frames: give the label movie the "
                                 "table was measured from")
            if not movie and "movie" in rows and rows["movie"].nunique() > 1:
                continue  # one array for several movies: drawn for none of them
            # by content: each row's object in its frame, with its size and centroid
            check_labels_match(arr, carry_options(table, rows), where=self.where(movie),
                               movie=movie or None)

    def where(self, movie: str) -> str:
        """The labels' name for a message: their file when known."""
        names = self.names if isinstance(self.names, Mapping) else {"": self.names}
        name = names.get(movie) or names.get("")
        return str(name) if name else (f"the labels of {movie}" if movie else "the labels")

    def movie_array(self, movie: str | None):
        labels = self.labels
        if isinstance(labels, Mapping):
            if movie is None:
                if len(labels) != 1:
                    return None
                return next(iter(labels.values()))
            return labels.get(movie)
        if len(self.movies) > 1:
            return None  # one array for several movies: which one is unknown
        return labels

    def mask(self, row: Mapping[str, Any]) -> np.ndarray | None:
        if self.labels is None:
            return None
        arr = self.movie_array(str(row["movie"]) if "movie" in row else None)
        if arr is None:
            return None
        frame = int(row["frame"])
        ndim = getattr(arr, "ndim", 0)
        if ndim == self.ndim + 1:  # a movie
            if not 0 <= frame < arr.shape[0]:
                return None
            image = np.asarray(arr[frame])
        elif ndim == self.ndim:  # one image (or volume)
            image = np.asarray(arr)
        else:
            return None
        mask = image == int(row["label"])
        if mask.ndim == 3:
            mask = mask.any(axis=0)  # a volume: its projection along z
        if not mask.any():
            return None
        rows, cols = np.nonzero(mask)
        pad = 3
        r0, r1 = max(rows.min() - pad, 0), min(rows.max() + pad + 1, mask.shape[0])
        c0, c1 = max(cols.min() - pad, 0), min(cols.max() + pad + 1, mask.shape[1])
        return np.pad(mask[r0:r1, c0:c1], 1)


def check_labels(labels, table: pd.DataFrame, names=None) -> None:
    """Refuse, in plain words (:class:`~napari_pfsdm.errors.InputError`), label arrays that
    are not the table's segmentation: not whole numbers (an image given by mistake), the
    wrong number of axes, fewer frames than the table has, or other objects than the table's
    rows in any frame (by id, size and centroid: another segmentation of the same shape, ids
    swapped, frames in another order; :func:`~napari_pfsdm.analysis.label_images.
    check_labels_match`). ``labels`` as for :func:`report_html`; None passes. ``names``: the
    labels' file (or movie → file), named in the message."""
    _Masks(labels, table, names).check(table)


def _draw_mask(ax, mask: np.ndarray | None, colour="0.25") -> None:
    ax.set_axis_off()
    if mask is None:
        ax.text(0.5, 0.5, "not in\nthe labels", ha="center", va="center", fontsize=7,
                color="0.5", transform=ax.transAxes)
        return
    ax.imshow(mask, cmap="Greys", vmin=0, vmax=2.5, interpolation="nearest")
    ax.contour(mask.astype(float), levels=[0.5], colors=[colour], linewidths=1.2)
    ax.set_aspect("equal")


# ------------------------------------------------------------------------------- sections
def _options_section(table: pd.DataFrame) -> str:
    opts = table_options(table)
    if not opts:
        return ('<p class="note">The table carries no options record (it was not read with '
                "its .csv.json sidecar).</p>")
    weight_names = {o.name for o in WEIGHT_OPTIONS}
    other = "3d" if int(opts.get("ndim", 2)) == 2 else "2d"

    def applies(name: str) -> bool:  # not the options of the other dimension's objects
        try:
            return option(name).dims != other
        except KeyError:
            return True

    rows = [(k, _shown(v), _meaning(k)) for k, v in opts.items()
            if k not in weight_names and applies(k)]
    rows += [(k, _shown(v), _meaning(k)) for k, v in opts.items() if k in weight_names]
    return _table_html(rows, ("option", "value", "what it means"))


def _methods_html(table: pd.DataFrame) -> str:
    """How the numbers were made, in a few plain sentences, with the table's units."""
    from .findings import time_words

    unit = space_unit_of(table)
    sizes = (f"Sizes are in {unit} (areas in {unit}², from each movie's pixel size)" if unit
             else "Sizes are in pixels (no pixel size was known)")
    sizes += f"; {time_words(table)}."
    return (
        "<p>Each object of each frame was measured by napari-pfsdm: its outline, its signed "
        "distance function pushed forward onto the unit disk, and the Fourier magnitudes of "
        "that picture ring by ring: shape features that do not change when the object is "
        "moved, turned, mirrored or scaled (its size is in the classic measures: area, "
        "lengths, as scikit-image's regionprops gives them). " + _e(sizes) + " An object is "
        "followed through time by its track (or its label when the labels follow it); the "
        "tests and predictions take each object once, with all its frames. Group tests are "
        "rank tests (Kruskal–Wallis, Mann–Whitney with Holm's correction); predictions are "
        "logistic regressions per family of features, fused, scored by repeated stratified "
        "splits of the objects.</p>")


def _counts_section(table: pd.DataFrame, measured: pd.DataFrame, left: pd.DataFrame) -> str:
    from .reduction import object_ids

    frames = sorted(int(f) for f in table["frame"].unique()) if len(table) else []
    rows = [("rows (one per frame and object)", f"{len(table):,}"),
            ("objects (followed through time)", f"{object_ids(table).nunique():,}"),
            ("frames", f"{len(frames):,}" + (f" ({frames[0]} … {frames[-1]})" if frames else ""))]
    if "movie" in table.columns:
        rows.append(("movies", f"{table['movie'].nunique():,}"))
    if TRACK_COLUMN in table.columns:
        tracked = (table[TRACK_COLUMN] != NO_TRACK).to_numpy()
        rows.append(("tracks", f"{object_ids(table)[tracked].nunique():,}"))
    groups = _group_names(table)
    if groups:
        ids = object_ids(table)
        per = table.assign(_o=ids).groupby("group")["_o"].nunique()
        with_group = int(ids[table["group"].astype(str) != ""].nunique())
        rows.append(("objects with a group", f"{with_group:,} of {ids.nunique():,}"))
        rows.append(("groups", "; ".join(f"{g}: {int(per.get(g, 0))} objects" for g in groups)))
    rows.append(("rows with features (in the analysis)", f"{len(measured):,}"))
    rows.append(("rows left out", f"{len(left):,}"))
    out = _table_html(rows, ("", "count"))
    if len(left):
        # one line per kind of reason ("The object is too small …: 276 pixels" and
        # "…: 311 pixels" are one kind), with the first one in full
        reasons = left["reason"].astype(str)
        kinds = reasons.str.split(":", n=1).str[0]
        why = [(kind, reasons[kinds == kind].iloc[0], int(n))
               for kind, n in kinds.value_counts().items()]
        out += "<h3>Why rows were left out</h3>" + _table_html(
            why, ("reason", "for example", "rows"), numeric=(2,))
        first = left.head(10).to_dict("records")
        cols = [c for c in ("movie", "frame", "label", TRACK_COLUMN, "reason") if c in left]
        out += ("<p class=\"note\">The first rows left out:</p>"
                + _table_html([[r[c] for c in cols] for r in first], cols))
    return out


def _trajectories_figure(scores: pd.DataFrame, explained: np.ndarray, when: str) -> str:
    from .reduction import object_ids

    names = _group_names(scores) or [""]
    if "group" not in scores.columns:
        scores = scores.assign(group="")
    scores = scores.assign(group=scores["group"].fillna("").astype(str))
    panels = names + (["(no group)"] if names != [""] and (scores["group"] == "").any() else [])
    panels = panels[:MAX_PANELS]
    n = len(panels)
    ncols = min(n, 3)
    nrows = -(-n // ncols)
    fig = _figure(4.0 * ncols, 3.6 * nrows)
    axes = np.atleast_1d(fig.subplots(nrows, ncols, sharex=True, sharey=True, squeeze=False)
                         ).ravel()
    ids = object_ids(scores)
    x, y = scores["shape_PC1"].to_numpy(float), scores["shape_PC2"].to_numpy(float)
    times = time_values(scores)
    fmin, fmax = float(times.min()), float(times.max())
    sc = None
    for ax, name in zip(axes, panels, strict=False):
        ax.scatter(x, y, s=4, color="0.88", zorder=0)  # every object, for reference
        key = "" if name == "(no group)" else name
        sub = scores[scores["group"] == key]
        objects = pd.unique(ids[sub.index])
        every = -(-len(objects) // MAX_LINES) if len(objects) else 1
        if every > 1:
            ax.text(0.01, 0.99, f"every {every}th of {len(objects):,} objects", fontsize=7,
                    va="top", transform=ax.transAxes, color="0.4")
        for oid in objects[::every]:
            obj = sub[ids[sub.index] == oid]
            obj = obj.iloc[np.argsort(time_values(obj), kind="stable")]
            ax.plot(obj["shape_PC1"], obj["shape_PC2"], "-", color="0.45", lw=0.8, zorder=1)
            sc = ax.scatter(obj["shape_PC1"], obj["shape_PC2"], c=time_values(obj), s=12,
                            cmap="viridis", vmin=fmin, vmax=fmax, zorder=2)
        ax.set_title(plot_text(name) if name else "all objects", fontsize=10)
        ax.set_xlabel(f"PC1 ({100 * explained[0]:.2g} %)")
        if len(explained) > 1:
            ax.set_ylabel(f"PC2 ({100 * explained[1]:.2g} %)")
    for ax in axes[n:]:
        ax.set_visible(False)
    if sc is not None:
        fig.colorbar(sc, ax=axes[:n].tolist(), label=when, shrink=0.8)
    return _img(fig, "trajectories per group in the PC1-PC2 plane")


def _over_time_section(table: pd.DataFrame, columns: Sequence[str]) -> str:
    from matplotlib.ticker import MaxNLocator

    from .over_time import numeric_columns, plot_over_time

    have = set(numeric_columns(table))
    cols = [c for c in columns if c in have]
    if not cols:
        return ('<p class="note">None of the measures asked for ('
                f"{_e(', '.join(columns))}) is in the table.</p>")
    ncols = min(len(cols), 2)
    nrows = -(-len(cols) // ncols)
    fig = _figure(5.4 * ncols, 3.2 * nrows)
    axes = np.atleast_1d(fig.subplots(nrows, ncols, squeeze=False)).ravel()
    for ax, col in zip(axes, cols, strict=False):
        plot_over_time(ax, table, col)
        if "time" not in table.columns:
            ax.xaxis.set_major_locator(MaxNLocator(integer=True))  # frames
        ax.set_title(plot_text(col), fontsize=10)
    for ax in axes[len(cols):]:
        ax.set_visible(False)
    from .glossary import describe_column

    notes = "".join(f"<li><b>{_e(c)}</b>: {_e(describe_column(c, space_unit=space_unit_of(table), time_unit=time_unit_of(table)))}</li>"  # noqa: E501
                    for c in cols)
    return (_img(fig, "measures over time") + "<p class=\"note\">Thin grey lines: each "
            "object; bands: each group's mean ± sd.</p>" f"<ul class=\"note\">{notes}</ul>")


def _loadings_figure(space, k: int, ndim: int = 2) -> str:
    from .shape_space import HARMONIC_WORDS

    lo = space.loadings(k)
    index = "Fourier index n" if ndim == 2 else "spherical-harmonic degree l"
    fig = _figure(4.2, 3.2)
    ax = fig.subplots()
    v = float(np.abs(lo).max()) or 1.0
    im = ax.imshow(lo, cmap="RdBu_r", vmin=-v, vmax=v, aspect="auto", origin="lower",
                   interpolation="nearest")
    ax.set_xlabel(index)
    ax.set_ylabel("ring (0 = centre)" if ndim == 2 else "shell (0 = centre)")
    ticks = range(lo.shape[1]) if lo.shape[1] <= 12 else range(0, lo.shape[1], 2)
    ax.set_xticks(list(ticks))
    from matplotlib.ticker import MaxNLocator

    ax.yaxis.set_major_locator(MaxNLocator(integer=True))
    ax.set_title(f"PC{k} loadings", fontsize=10)
    fig.colorbar(im, ax=ax, label="loading")
    n_max = int(np.abs(lo).sum(axis=0).argmax())
    word = f" ({HARMONIC_WORDS[n_max]})" if ndim == 2 and n_max < len(HARMONIC_WORDS) else ""
    return (_img(fig, f"PC{k} loadings, ring by {index}"),
            f"its largest loadings are at {index.rsplit(' ', 1)[0]} {n_max}{word}")


def modes_figure(scores: pd.DataFrame, k: int, masks, several: bool):
    """The real objects nearest the mean −2σ … +2σ along PC ``k``, each captioned under its
    picture (where it is, on at most three lines): a figure whose captions never overlap."""
    from .shape_space import shape_modes

    modes = shape_modes(scores, k)
    fig = _figure(1.45 * len(modes), 2.3)
    axes = fig.subplots(1, len(modes))
    for ax, row in zip(axes, modes.to_dict("records"), strict=True):
        _draw_mask(ax, masks.mask(row))
        ax.set_title(f"{row['sigma']:+g}σ", fontsize=8)
        ax.text(0.5, -0.03, _wrapped(plot_text(_where(row, several)), 16),
                transform=ax.transAxes,
                ha="center", va="top", fontsize=6, color="0.25")
    return fig


def _modes_figure(scores: pd.DataFrame, k: int, masks: _Masks, several: bool) -> str:
    return _img(modes_figure(scores, k, masks, several),
                f"real objects at -2 sigma to +2 sigma along PC{k}")


def _pc_section(table: pd.DataFrame, measured: pd.DataFrame, space, scores: pd.DataFrame,
                masks: _Masks, several: bool) -> str:
    sentences: list[str] = []
    classic = {"axis_major_length", "axis_minor_length", "circularity", "solidity"}
    if classic <= set(measured.columns):
        from .interpretation import explain_components, table_measures

        plain = scores.rename(columns={f"shape_PC{i}": f"PC{i}"
                                       for i in range(1, len(space.components_) + 1)})
        try:
            sentences = explain_components(plain, table_measures(measured),
                                           None, n=N_PCS)
        except (KeyError, ValueError):
            sentences = []
    out = []
    for k in range(1, min(N_PCS, len(space.components_)) + 1):
        share = 100 * space.explained_variance_ratio_[k - 1]
        out.append(f"<h3>PC{k} ({share:.2g} % of the variance)</h3>")
        said = [s for s in sentences if s.startswith(f"PC{k} ")]
        if said:
            out.append(f"<p>{_e(said[0])}.</p>")
        elif not classic <= set(measured.columns):
            out.append('<p class="note">The table has no classic measures (circularity, '
                       "solidity, axis lengths) to compare the PC with.</p>")
        img, words = _loadings_figure(space, k, masks.ndim)
        out.append(f'<div class="row">{img}')
        if masks:
            out.append(_modes_figure(scores, k, masks, several))
        out.append(f'</div><p class="note">Left: the loadings ({_e(words)}); red: features '
                   "that grow along the PC. " + ("Right: the real objects nearest to the "
                                                 "mean −2σ … +2σ along it."
                                                 if masks else "The outlines of the objects "
                                                 "along the PC need the labels (the label "
                                                 "movie): give them to draw the objects.")
                   + "</p>")
    return "".join(out)


def _gallery_section(scores: pd.DataFrame, masks: _Masks, several: bool, n_pcs: int) -> str:
    if not masks:
        return ('<p class="note">The gallery needs the labels (the label movie) to draw the '
                "objects' outlines; give them (``--labels LABELS.tif``, or ``labels=`` in "
                "Python).</p>")
    out = []
    for k in range(1, n_pcs + 1):
        col = f"shape_PC{k}"
        order = np.argsort(scores[col].to_numpy(float), kind="stable")
        ends = (("lowest", order[:GALLERY]), ("highest", order[::-1][:GALLERY]))
        out.append(f"<h3>PC{k}</h3><div class=\"gallery\">")
        for name, idx in ends:
            out.append(f'<div class="end"><b>{name}</b></div>')
            for i in idx:
                row = scores.iloc[int(i)].to_dict()
                fig = _figure(1.3, 1.3)
                _draw_mask(fig.subplots(), masks.mask(row),
                           colour="tab:blue" if name == "lowest" else "tab:red")
                where = _where(row, several)
                group = f"<br>{_e(row['group'])}" if row.get("group") else ""
                out.append(f"<figure>{_img(fig, where)}<figcaption>{_e(where)}<br>"
                           f"PC{k} = {row[col]:+.3g}{group}</figcaption></figure>")
        out.append("</div>")
    return "".join(out)


def _nearest_section(measured: pd.DataFrame, scores: pd.DataFrame, masks: _Masks,
                     several: bool, elastic_weight: float) -> str:
    """A few objects spread along PC1 and their nearest shapes among all measured objects
    (:class:`~napari_pfsdm.analysis.neighbours.NeighbourSearch`: the PF-SDM distance, with the
    elastic outline term when ``elastic_weight`` > 0), drawn as outlines (the labels given)
    or listed."""
    from .neighbours import NeighbourSearch

    n = len(measured)
    k = min(NEAREST_SHOWN, n - 1)
    order = np.argsort(scores["shape_PC1"].to_numpy(float), kind="stable")
    picks = np.unique(order[np.linspace(0, n - 1, min(NEAREST_QUERIES, n)).round().astype(int)])
    found = NeighbourSearch(measured, elastic_weight=elastic_weight).rows(picks, k)
    term = (f"the PF-SDM distance with the elastic outline term (μ = {elastic_weight:g})"
            if elastic_weight else "the PF-SDM distance")
    note = (f'<p class="note">{len(picks)} objects spread along PC1 (first column) and their '
            f"{k} nearest shapes among the {n:,} measured objects, under {term}, with the "
            "distances.")
    if not found.exact:
        note += (" With the elastic term the search is approximate: "
                 f"{found.certified.mean():.0%} of these rows are certified those of the "
                 "full distance matrix, the others the nearest among each object's candidates.")
    out = [note + "</p>"]
    for q, idx, dist in zip(picks, found.indices, found.distances, strict=True):
        rows = [(measured.iloc[int(q)].to_dict(), None)]
        rows += [(measured.iloc[int(j)].to_dict(), d) for j, d in zip(idx, dist, strict=True)
                 if j >= 0]
        if not masks:
            out.append(_table_html([[_where(r, several), "" if d is None else f"{d:.4g}"]
                                    for r, d in rows], ["object", "distance"]))
            continue
        out.append('<div class="gallery">')
        for r, d in rows:
            fig = _figure(1.3, 1.3)
            _draw_mask(fig.subplots(), masks.mask(r),
                       colour="tab:red" if d is None else "0.25")
            where = _where(r, several)
            text = "this one" if d is None else f"d = {d:.3g}"
            out.append(f"<figure>{_img(fig, where)}<figcaption>{_e(where)}<br>{text}"
                       "</figcaption></figure>")
        out.append("</div>")
    return "".join(out)


# ------------------------------------------------------------------------------- the page
def report_html(
    table: pd.DataFrame,
    *,
    groups: Mapping | pd.DataFrame | None = None,
    predictions=None,
    prediction_info: Mapping[str, Any] | None = None,
    labels=None,
    title: str | None = None,
    columns: Sequence[str] = REPORT_COLUMNS,
    source: str | None = None,
    findings: Sequence[tuple[str, str | float]] | None = None,
    elastic_weight: float | None = None,
) -> str:
    """The report of a run as one self-contained HTML text (no links out, no script): the
    findings first (what differs between the groups, the prediction), then the trajectories,
    the measures over time, what each PC means, a gallery; counts, options and methods last.

    Parameters
    ----------
    table : DataFrame
        A feature table with its options (:func:`napari_pfsdm.measure`,
        :func:`napari_pfsdm.read_table`), of one movie or many.
    groups : mapping or DataFrame, optional
        Object → group (the ``track_id`` of a linked table, else the label), or a groups
        table (:func:`~napari_pfsdm.analysis.groups.read_groups`); default: the table's own
        ``group`` column, if any.
    predictions : Prediction or DataFrame, optional
        What :func:`~napari_pfsdm.analysis.outcome.predict_outcome` returned, or a
        predictions table (``p_<group>`` columns) with ``prediction_info``, its sidecar (the
        ``curve``, ``balanced_accuracy`` and ``confusion`` that ``pfsdm predict`` writes
        there).
    labels : ndarray or mapping, optional
        The label movie (T, Y, X) or image (Y, X); a mapping movie → array for a table of
        several movies. Without it the report says the outlines need it.
    title : str, optional
    columns : sequence of str
        Measures drawn over time (those the table has).
    source : str, optional
        Where the table came from (a file name), shown under the title.
    findings : sequence of (measure, summary or time), optional
        The measures tested between the groups (:func:`~napari_pfsdm.analysis.findings.
        default_findings` when not given; ``shape_PC1`` is the report's own PCA).
    elastic_weight : float, optional
        μ of the elastic outline term in the distance of the "Nearest shapes" section (default
        0: the PF-SDM distance; :data:`napari_pfsdm.RECOMMENDED_ELASTIC_WEIGHT` for retrieval
        among articulated or detailed outlines; the table must carry the signatures).

    Returns
    -------
    str
        The HTML page.
    """
    from .features import split_failed
    from .findings import Terms, default_findings, findings_html, prediction_html, prediction_parts
    from .shape_space import ShapePCA

    if not {"frame", "label"} <= set(table.columns):
        raise InputError("the table has no frame and label columns: give a feature table "
                         "from measure (pfsdm measure)")
    table = _with_groups(table, groups)
    measured, left = split_failed(table)
    title = title or "PF-SDM report"
    several = "movie" in table.columns and table["movie"].nunique() > 1
    masks = _Masks(labels, table)
    masks.check(table)
    terms = Terms()
    scores = space = None
    if len(measured) >= 2:
        space = ShapePCA(n_components=N_PCS, channel="shape")
        scores = space.fit_transform(measured)
        if "group" in measured.columns and "group" not in scores.columns:
            scores["group"] = measured["group"].to_numpy()
    tested = measured if scores is None else measured.assign(
        shape_PC1=scores["shape_PC1"].to_numpy())
    parts = prediction_parts(predictions, prediction_info)
    colours = _colours(_group_names(table))
    found = findings_html(tested, default_findings(tested) if findings is None else findings,
                          colours, terms)
    if parts is not None:
        found += ("<h3>Predicting the groups from the features</h3>"
                  + prediction_html(parts, terms, measured))
    sections: list[tuple[str, str, str]] = [("findings", "What differs between the groups",
                                             found)]
    if scores is not None:
        n_pcs = min(N_PCS, len(space.components_))
        traj = (_trajectories_figure(scores, space.explained_variance_ratio_,
                                     time_label(measured)) if n_pcs >= 2
                else '<p class="note">Only one principal component: no plane to draw.</p>')
        sections.append(("trajectories", "Trajectories per group",
                         traj + f'<p class="note">Each object\'s path through the PC1–PC2 '
                         f"plane ({terms('PC')}) of the shape features, weighted as the "
                         f"PF-SDM distance; points coloured by {_e(time_label(measured))}; grey "
                         "dots: every object.</p>"))
        sections.append(("over-time", "Measures over time", _over_time_section(measured,
                                                                               columns)))
        sections.append(("pcs", "What each PC means",
                         _pc_section(table, measured, space, scores, masks, several)))
        sections.append(("gallery", "Gallery: the most extreme objects per PC",
                         _gallery_section(scores, masks, several, n_pcs)))
        sections.append(("nearest", "Nearest shapes",
                         _nearest_section(measured, scores, masks, several,
                                          check_elastic_weight(elastic_weight))))
    else:
        sections.append(("over-time", "Measures over time", _over_time_section(measured,
                                                                               columns)))
        sections.append(("pcs", "What each PC means", f'<p class="note">Only {len(measured)} '
                         "row(s) have features: no PCA.</p>"))
    sections.append(("counts", "Counts", _counts_section(table, measured, left)))
    sections.append(("options", "Options and methods", _methods_html(table)
                     + _options_section(table)))
    when = datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d %H:%M UTC")
    toc = "".join(f'<a href="#{a}">{_e(h)}</a>' for a, h, _ in sections)
    body = "".join(f'<section id="{a}"><h2>{_e(h)}</h2>{content}</section>'
                   for a, h, content in sections)
    src = f" from <code>{_e(source)}</code>" if source else ""
    return ("<!DOCTYPE html>\n"
            '<html lang="en"><head><meta charset="utf-8">'
            f'<meta name="generator" content="{GENERATOR} {_e(__version__)}">'
            '<meta name="viewport" content="width=device-width, initial-scale=1">'
            f"<title>{_e(title)}</title><style>{_CSS}</style></head><body>"
            f"<h1>{_e(title)}</h1>"
            f'<p class="note">Written by napari-pfsdm {_e(__version__)} on {when}{src}.</p>'
            f'<p class="toc">{toc}</p>{body}</body></html>\n')
