"""The report's findings: what differs between the groups, in plain words and physical units.

For each chosen measure (:func:`default_findings`: the size at the last time and its growth,
the circularity at the last time, PC1 of the shape at the last time), one value per object and
the test between the groups (:mod:`napari_pfsdm.analysis.group_stats`), drawn as each group's
objects; then the prediction of the groups from the features (balanced accuracy per family and
fused, against chance, with the confusion matrix). Terms a biologist may not know are glossed
where they first appear (:class:`Terms`).
"""

from __future__ import annotations

import textwrap
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
import pandas as pd

from ..errors import InputError
from .group_stats import compare_groups, number, object_values, value_words
from .html_parts import escaped, figure, image, table_html
from .physical import time_unit_of, time_values
from .plot_text import plot_text

__all__ = ["TERMS", "Terms", "default_findings", "findings_html", "prediction_html"]

#: The words the report glosses where they first appear.
TERMS = {
    "PC": "principal component: a direction of the shape features along which the objects "
          "differ most; PC1 is the first",
    "balanced accuracy": "the share of each group's objects predicted right, averaged over the "
                         "groups; chance is 1 / the number of groups",
    "Kruskal-Wallis": "a test of whether the groups' values come from one distribution, on "
                      "their ranks (no assumption on their shape)",
    "Mann-Whitney U": "the same test for two groups",
    "Holm's correction": "p-values of several pairs made larger so that the chance of any "
                         "false finding stays below 5 %",
    "rank-biserial": "the share of pairs of objects (one of each group) where the first is "
                     "larger, minus the share where it is smaller: from −1 to 1",
    "epsilon squared": "the share of the ranks' spread that the groups explain: from 0 to 1",
    "confusion matrix": "how often the objects of each group (rows) were predicted as each "
                        "group (columns) on the test splits",
    "fused": "the three families' predictions averaged with weights chosen on the training "
             "objects only",
}


class Terms:
    """Glosses each term of :data:`TERMS` the first time :meth:`__call__` names it."""

    def __init__(self) -> None:
        self.said: set[str] = set()

    def __call__(self, term: str) -> str:
        """``term`` as HTML, with its gloss in parentheses the first time."""
        if term in self.said or term not in TERMS:
            return escaped(term)
        self.said.add(term)
        return f'{escaped(term)} <span class="gloss">({escaped(TERMS[term])})</span>'


def default_findings(table: pd.DataFrame) -> list[tuple[str, str | float]]:
    """The measures a report tests between groups, each with its summary (``"slope"``,
    ``"mean"``…) or its time: the size at the last time and its change over time, the
    circularity at the last time, PC1 of the shape at the last time (when the scores are
    in the table)."""
    times = np.unique(time_values(table)) if len(table) else np.zeros(0)
    if not len(times):
        return []
    last = float(times[-1])
    size = "area" if "area" in table.columns else "volume" if "volume" in table.columns else None
    out: list[tuple[str, str | float]] = []
    if size:
        out.append((size, last))
        if len(times) > 1:
            out.append((size, "slope"))
    for column in ("circularity", "shape_PC1"):
        if column in table.columns:
            out.append((column, last))
    return out


def _strip_figure(values: pd.DataFrame, names: Sequence[str], colours: Mapping, what: str):
    fig = figure(max(3.2, 0.9 * len(names) + 1.6), 2.8)
    ax = fig.subplots()
    rng = np.random.default_rng(0)
    data = [values.loc[values["group"] == g, "value"].to_numpy(float) for g in names]
    ax.boxplot(data, positions=range(len(names)), widths=0.55, showfliers=False,
               medianprops={"color": "k"})
    for i, (g, v) in enumerate(zip(names, data, strict=True)):
        ax.scatter(i + rng.uniform(-0.18, 0.18, len(v)), v, s=10, color=colours[g],
                   alpha=0.8, zorder=3)
    ax.set_xticks(range(len(names)), [plot_text(n) for n in names], fontsize=8)
    ax.set_ylabel("\n".join(textwrap.wrap(plot_text(what), 30)), fontsize=8)  # fits beside the axis
    ax.tick_params(labelsize=8)
    return fig


def _group_rows(test) -> list[tuple]:
    return [(r.group, r.n, number(r.median), f"{number(r.q1)} – {number(r.q3)}")
            for r in test.groups.itertuples()]


def findings_html(table: pd.DataFrame, findings: Sequence[tuple[str, str | float]],
                  colours: Mapping, terms: Terms) -> str:
    """The findings' HTML: per measure, the sentence of its test, each group's median and
    spread, and each group's objects drawn; measures a table lacks are said to be absent."""
    names = sorted(set(table["group"].astype(str)) - {""}) if "group" in table.columns else []
    if len(names) < 2:
        return ('<p class="note">No groups to compare: give the objects\' groups (a groups '
                "file with --groups, or groups= in Python) to see what differs between "
                "them.</p>")
    out = []
    for measure, when in findings:
        if measure not in table.columns:
            out.append(f'<p class="note">The table has no {escaped(measure)} column.</p>')
            continue
        at, summary = (None, str(when)) if isinstance(when, str) else (float(when), None)
        try:
            values = object_values(table, measure, at=at, summary=summary)
            what = value_words(table, measure, summary or "at", at)
            test = compare_groups(values, what=what)
        except InputError as exc:
            out.append(f'<p class="note">{escaped(measure)}: {escaped(exc)}</p>')
            continue
        out.append(f"<h3>{escaped(what)}</h3>")
        out.append(f"<p>{_test_words(test, terms)}</p>")
        img = image(_strip_figure(values, list(test.groups["group"]), colours, what),
                    f"each group's objects: {what}")
        out.append(f'<div class="row">{img}'
                   + table_html(_group_rows(test), ("group", "objects", "median",
                                                   "middle half (25 %–75 %)"),
                                numeric=(1, 2, 3)) + "</div>")
    return "".join(out)


#: The name of Holm's correction, as :data:`TERMS` knows it.
HOLM = "Holm's correction"


def _test_words(test, terms: Terms) -> str:
    """The test's sentences with its terms glossed."""
    o = test.overall
    p = o["p_value"]
    verdict = "differ" if p < 0.05 else "do not differ detectably"
    shown_p = f"= {p:.2g}" if p >= 1e-4 else "< 0.0001"
    effect = "rank-biserial" if o["effect_measure"] == "rank-biserial correlation" \
        else o["effect_measure"]
    words = (f"The groups {verdict} ({terms(o['test'])}, p {shown_p}; {terms(effect)} "
             f"{o['effect_size']:.2f}).")
    if len(test.pairs) > 1:
        differ = test.pairs[test.pairs["p_holm"] < 0.05]
        if len(differ):
            pairs = "; ".join(
                (f"{escaped(r.first)} &gt; {escaped(r.second)}" if r.effect_size > 0 else
                 f"{escaped(r.second)} &gt; {escaped(r.first)}")
                + f" (r = {abs(r.effect_size):.2f})" for r in differ.itertuples())
            words += f" Pairs that differ after {terms(HOLM)}: {pairs}."
        else:
            words += f" No pair differs after {terms(HOLM)}."
    return words


def frame_times(table: pd.DataFrame | None) -> dict[int, float]:
    """frame → its time in a table (the first movie's), {} without times."""
    if table is None or "time" not in table.columns or not len(table):
        return {}
    first = table[table["movie"] == table["movie"].iloc[0]] if "movie" in table else table
    return {int(f): float(t) for f, t in first.drop_duplicates("frame")[["frame", "time"]]
            .itertuples(index=False)}


def _frames_words(frames: Sequence[int] | None, table: pd.DataFrame | None) -> str:
    """``frames 0, 1, 2 (days 2, 5, 8)``: the frames used and, when known, their times."""
    if not frames:
        return "the frames given"
    words = f"frames {', '.join(map(str, frames))}"
    at = frame_times(table)
    if at and all(int(f) in at for f in frames):
        unit = time_unit_of(table)
        name = "days" if unit == "day" else (f"times ({unit})" if unit else "times")
        words += f" ({name} {', '.join(f'{at[int(f)]:g}' for f in frames)})"
    return words


def prediction_html(parts: tuple, terms: Terms, table: pd.DataFrame | None = None) -> str:
    """The prediction's HTML: balanced accuracy per family and fused against chance, the
    confusion matrix, in words; with the feature ``table``, frames are said with their
    times."""
    curve, summary, probs, groups, frames, confusion = parts
    out = []
    if len(summary):
        chance = float(summary.loc["chance", "mean"]) if "chance" in summary.index else \
            1.0 / max(len(groups), 2)
        if "fused" in summary.index:
            fused = summary.loc["fused"]
            best = summary.drop(index=[i for i in ("fused", "chance") if i in summary.index])
            alone = "; ".join(f"{_family(m)} alone {r['mean']:.2f}"
                              for m, r in best.iterrows())
            used = _frames_words(frames, table)
            out.append(
                f"<p>From {escaped(used)}, the {terms('fused')} model tells the "
                f"{len(groups)} groups apart with a {terms('balanced accuracy')} of "
                f"{fused['mean']:.2f} ± {0.0 if pd.isna(fused['std']) else fused['std']:.2f} "
                f"(chance {chance:.2f}); {escaped(alone)}.</p>")
        rows = [(_family(m), f"{r['mean']:.2f}", f"{r['std']:.2f}" if pd.notna(r["std"])
                 and m != "chance" else "") for m, r in summary.iterrows()]
        out.append(table_html(rows, ("features", "balanced accuracy", "sd"), numeric=(1, 2)))
    if confusion is not None and len(confusion):
        counts = np.asarray(confusion, float)
        share = counts / np.maximum(counts.sum(axis=1, keepdims=True), 1)
        rows = [[g] + [f"{int(c)} ({100 * s:.0f} %)" for c, s in zip(row, srow, strict=True)]
                for g, row, srow in zip(groups, counts, share, strict=True)]
        out.append(f"<h3>The {terms('confusion matrix')}</h3>")
        out.append(table_html(rows, ["true group ↓ / predicted →", *map(str, groups)],
                              numeric=tuple(range(1, len(groups) + 1))))
    scored = int((probs["group"].astype(str) != "").sum()) if "group" in probs.columns else None
    total = len(probs)
    counted = (f"{scored} of {total} objects have a group and were scored; the others were "
               "predicted only" if scored is not None and scored < total else
               f"{total} objects scored")
    out.append(f'<p class="note">{escaped(counted)}; groups: '
               f"{escaped(', '.join(map(str, groups)))}.</p>")
    if len(curve) and {"last_frame", "mean"} <= set(curve.columns):
        out.append(_curve_figure(curve, chance=1.0 / max(len(groups), 2), table=table))
    return "".join(out)


def _family(method: str) -> str:
    from .outcome import FAMILY_WORDS

    name = str(method).replace(" alone", "")
    return FAMILY_WORDS.get(name, name)


def _curve_figure(curve: pd.DataFrame, chance: float, table: pd.DataFrame | None = None
                  ) -> str:
    from matplotlib.ticker import MaxNLocator

    fig = figure(5.4, 3.0)
    ax = fig.subplots()
    at = frame_times(table)
    timed = bool(at) and all(int(f) in at for f in curve["last_frame"])
    x = np.array([at[int(f)] for f in curve["last_frame"]]) if timed else \
        curve["last_frame"].to_numpy(float)
    m = curve["mean"].to_numpy(float)
    s = curve["std"].fillna(0).to_numpy(float) if "std" in curve else np.zeros_like(m)
    ax.fill_between(x, m - s, m + s, alpha=0.25, color="tab:blue", lw=0)
    ax.plot(x, m, "-o", color="tab:blue", ms=4, label="fused model (mean ± sd)")
    ax.axhline(chance, color="0.5", ls="--", lw=1, label="chance")
    ax.set_ylim(0, 1.02)
    if timed:
        unit = time_unit_of(table)
        ax.set_xlabel(f"last time used{f' ({unit})' if unit else ''}")
    else:
        ax.set_xlabel("last frame used")
        ax.xaxis.set_major_locator(MaxNLocator(integer=True))
    ax.set_ylabel("balanced accuracy")
    ax.legend(fontsize=8, loc="lower right")
    ax.set_title("How early the groups can be predicted", fontsize=10)
    return (image(fig, "balanced accuracy against the last frame used")
            + '<p class="note">Each point: the balanced accuracy over repeated stratified '
            "splits, using the frames up to that one; the fusion weights are chosen inside "
            "each training split only.</p>")


def prediction_parts(predictions, info: Mapping[str, Any] | None):
    """(curve, summary, probabilities, groups, frames, confusion) from a
    :class:`~napari_pfsdm.analysis.outcome.Prediction` or a predictions table and its
    sidecar (``info``); None without predictions."""
    if predictions is None:
        return None
    if isinstance(predictions, pd.DataFrame):
        info = dict(info or {})
        curve = pd.DataFrame(info.get("curve") or [])
        summary = pd.DataFrame(info.get("balanced_accuracy") or [])
        if len(summary) and "method" in summary.columns:
            summary = summary.set_index("method")
        groups = [c[2:] for c in predictions.columns if str(c).startswith("p_")]
        conf = (info.get("confusion") or {}).get("counts")
        if (info.get("confusion") or {}).get("groups"):
            groups = list(info["confusion"]["groups"])
        return curve, summary, predictions, groups, info.get("frames"), conf
    if getattr(predictions, "curve", None) is None:
        raise InputError("predictions must be a Prediction (predict_outcome) or a "
                         "predictions table with p_<group> columns")
    return (predictions.curve, predictions.summary, predictions.probabilities,
            list(predictions.groups), predictions.frames,
            getattr(predictions, "confusion", None))


def time_words(table: pd.DataFrame) -> str:
    """How the report's times are counted, in words."""
    unit = time_unit_of(table)
    if "time" in table.columns:
        return f"times in {unit}" if unit else "times as given (no unit)"
    return "times are frame numbers (the table has no times)"
