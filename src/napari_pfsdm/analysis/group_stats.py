"""Do the groups differ? One value per object (a measure at a time, or a summary of it over
time such as its growth rate) and the tests between groups, in numbers and in words.

:func:`object_values` gives each object (``movie`` and its track or label) one value of a
measure: at a time of the table's (``at``: the rows at that time, their mean when a time was
imaged twice), or over its time course (``summary``: ``"slope"``, the least-squares change per
unit of time; ``"mean"``; ``"first"``; ``"last"``). :func:`compare_groups` tests them:
Kruskal–Wallis for three groups or more (Mann–Whitney's U for two), then every pair by
Mann–Whitney with Holm's correction, with effect sizes (ε² for Kruskal–Wallis, the rank-biserial
correlation for a pair: the share of pairs of objects where the first group's is larger minus
the share where it is smaller) and each group's median and count. Rank tests: no assumption on
the shape of the values' distribution; objects, not frames, are the units (a movie's frames
are one object's, never independent samples).

Examples
--------
>>> import pandas as pd
>>> t = pd.DataFrame({"movie": ["a", "a", "b", "b", "c", "c", "d", "d"],
...                   "frame": [0, 1] * 4, "time": [2.0, 5.0] * 4, "label": [1] * 8,
...                   "area": [10, 16, 11, 17, 20, 35, 22, 40],
...                   "group": ["x", "x", "x", "x", "y", "y", "y", "y"]})
>>> v = object_values(t, "area", summary="slope")
>>> v["value"].round(2).tolist()
[2.0, 2.0, 5.0, 6.0]
>>> compare_groups(v).pairs[["first", "second", "effect_size"]].values.tolist()
[['x', 'y', -1.0]]
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import pandas as pd

from ..core.columns import unit_text
from ..errors import InputError
from .physical import space_unit_of, time_label, time_unit_of, time_values

__all__ = ["GroupTest", "SUMMARIES", "compare_groups", "number", "object_values",
           "value_words"]

#: The summaries of a measure over an object's time course.
SUMMARIES = ("slope", "mean", "first", "last")


def _objects(table: pd.DataFrame) -> pd.Series:
    from .reduction import object_ids

    return object_ids(table)


def object_values(table: pd.DataFrame, measure: str, *, at: float | None = None,
                  summary: str | None = None, group: str = "group",
                  keep: Sequence[str] = ()) -> pd.DataFrame:
    """One value of ``measure`` per object: at the time ``at`` (the table's time unit, or its
    frame when it has no times), or its ``summary`` over time (:data:`SUMMARIES`; default
    ``"mean"``).

    keep : sequence of str
        Other columns to carry (e.g. the groups file's other grouping columns): each object's
        first row's.

    Returns
    -------
    DataFrame
        ``object``, ``movie`` (when the table has movies), ``group``, ``keep``, ``value``,
        ``n_times`` (the object's times used). :func:`value_words` says in words what the
        value is, with its unit.

    Raises
    ------
    InputError
        An unknown measure or summary, both ``at`` and ``summary``, a time no object has.
    """
    if measure not in table.columns or not pd.api.types.is_numeric_dtype(table[measure]):
        numeric = [c for c in table.columns if pd.api.types.is_numeric_dtype(table[c])][:8]
        raise InputError(f"the table has no numeric column {measure!r}; e.g. "
                         f"{', '.join(numeric)}")
    if at is not None and summary is not None:
        raise InputError("give either a time (--at) or a summary over time (--summary), "
                         "not both")
    summary = summary or ("at" if at is not None else "mean")
    if summary not in (*SUMMARIES, "at"):
        raise InputError(f"the summary must be one of {', '.join(SUMMARIES)}; got "
                         f"{summary!r}")
    ok = np.isfinite(table[measure].to_numpy(float))
    if "error" in table.columns:
        ok &= table["error"].fillna("").astype(str).eq("").to_numpy()
    kept = table.loc[ok]
    wanted = list(dict.fromkeys([c for c in ("movie", group, *keep) if c in kept.columns]
                                + [measure]))
    rows = kept[wanted].assign(_object=_objects(kept).to_numpy(), _time=time_values(kept))
    if summary == "at":
        rows = _at(rows, float(at), table)
    keys = [c for c in ("movie", group) if c in rows.columns]
    extra = [c for c in keep if c in rows.columns and c not in keys]
    out = []
    for obj, g in rows.groupby("_object", sort=False):
        value = _summarised(g, measure, summary)
        row = {"object": obj, **{k: g[k].iloc[0] for k in keys + extra}, "value": value,
               "n_times": int(g["_time"].nunique())}
        out.append(row)
    return pd.DataFrame(out, columns=["object", *keys, *extra, "value", "n_times"])


def _at(rows: pd.DataFrame, at: float, table: pd.DataFrame) -> pd.DataFrame:
    times = np.unique(rows["_time"].to_numpy())
    hit = np.isclose(rows["_time"].to_numpy(), at, rtol=0, atol=1e-9 * max(1.0, abs(at)))
    if not hit.any():
        shown = ", ".join(f"{t:g}" for t in times[:12]) + (" …" if len(times) > 12 else "")
        raise InputError(f"no object has a {time_label(table)} of {at:g}; the table's are "
                         f"{shown}")
    return rows[hit]


def _summarised(g: pd.DataFrame, measure: str, summary: str) -> float:
    values = g[measure].to_numpy(float)
    times = g["_time"].to_numpy(float)
    order = np.argsort(times, kind="stable")
    if summary in ("mean", "at"):
        return float(values.mean())
    if summary == "first":
        return float(values[order[0]])
    if summary == "last":
        return float(values[order[-1]])
    if np.unique(times).size < 2:
        return float("nan")  # a slope needs two times
    return float(np.polyfit(times, values, 1)[0])


def value_words(table: pd.DataFrame, measure: str, summary: str, at: float | None = None
                ) -> str:
    """What an object's value is, with its unit: ``area at time 30 day (µm²)``,
    ``growth rate of area (µm² per day)``."""
    from .glossary import unit_of

    unit = unit_text(unit_of(measure), space_unit_of(table), time_unit_of(table))
    t_unit = time_unit_of(table) or ("frame" if "time" not in table.columns else "")
    if summary == "at":
        if t_unit == "day":
            when = f"day {at:g}"
        elif t_unit == "frame":
            when = f"frame {at:g}"
        else:
            when = f"{at:g} {t_unit}".strip() if t_unit else f"time {at:g}"
        return f"{measure} at {when}" + (f" ({unit})" if unit else "")
    if summary == "slope":
        per = f" per {t_unit}" if t_unit else " per unit of time"
        return f"change of {measure}{per}" + (f" ({unit}{per})" if unit else "")
    return f"{summary} of {measure} over time" + (f" ({unit})" if unit else "")


@dataclass
class GroupTest:
    """What :func:`compare_groups` found.

    Attributes
    ----------
    groups : DataFrame
        Per group: ``group``, ``n``, ``median``, ``q1``, ``q3`` of the values.
    overall : dict
        ``test`` (``"Kruskal-Wallis"`` or ``"Mann-Whitney U"``), ``statistic``, ``p_value``,
        ``effect_size`` and ``effect_measure`` (ε², or the rank-biserial correlation).
    pairs : DataFrame
        Every pair of groups: ``first``, ``second``, ``U``, ``p_value``, ``p_holm``,
        ``effect_size`` (rank-biserial: > 0 when ``first``'s values are larger), medians.
    value : str
        What the values are, in words with their unit.
    """

    groups: pd.DataFrame
    overall: dict
    pairs: pd.DataFrame
    value: str

    def table(self) -> pd.DataFrame:
        """One table of the results: the overall test, every pair, every group."""
        rows = [{"comparison": "all groups", "test": self.overall["test"],
                 "statistic": self.overall["statistic"], "p_value": self.overall["p_value"],
                 "p_holm": self.overall["p_value"], "effect_size": self.overall["effect_size"],
                 "effect_measure": self.overall["effect_measure"],
                 "n": int(self.groups["n"].sum())}]
        for r in self.pairs.itertuples():
            rows.append({"comparison": f"{r.first} vs {r.second}", "test": "Mann-Whitney U",
                         "statistic": r.U, "p_value": r.p_value, "p_holm": r.p_holm,
                         "effect_size": r.effect_size,
                         "effect_measure": "rank-biserial correlation",
                         "n": int(r.n_first + r.n_second)})
        for r in self.groups.itertuples():
            rows.append({"comparison": f"group {r.group}", "test": "", "n": int(r.n),
                         "median": r.median, "q1": r.q1, "q3": r.q3})
        out = pd.DataFrame(rows)
        out.insert(0, "value", self.value)
        return out

    def sentences(self, alpha: float = 0.05) -> list[str]:
        """The findings in plain words."""
        o = self.overall
        medians = "; ".join(f"{r.group} {number(r.median)} (n = {r.n})"
                            for r in self.groups.itertuples())
        verdict = "differ" if o["p_value"] < alpha else "do not differ detectably"
        out = [f"{self.value}: the groups {verdict} ({o['test']}, p {_p(o['p_value'])}, "
               f"{o['effect_measure']} {o['effect_size']:.2f}). Medians: {medians}."]
        if len(self.pairs) > 1:
            differ = self.pairs[self.pairs["p_holm"] < alpha]
            if len(differ):
                said = "; ".join(
                    (f"{r.first} > {r.second}" if r.effect_size > 0 else
                     f"{r.second} > {r.first}")
                    + f" (p {_p(r.p_holm)}, r = {abs(r.effect_size):.2f})"
                    for r in differ.itertuples())
                out.append(f"Pairs that differ after Holm's correction: {said}.")
            else:
                out.append("No pair of groups differs after Holm's correction.")
        return out


def number(x: float) -> str:
    """A value as a person reads it: three significant digits, thousands grouped.

    >>> [number(v) for v in (3234567.0, 75412.3, 999.7, 123.4, 0.8721)]
    ['3,230,000', '75,400', '1,000', '123', '0.872']
    """
    if not np.isfinite(x):
        return "n/a"
    size = abs(float(x))
    if size >= 999.5:
        digits = int(np.floor(np.log10(size))) + 1
        return f"{round(float(x), 3 - digits):,.0f}"
    if size >= 99.95:
        return f"{float(x):.0f}"
    return f"{float(x):.3g}"


def _p(p: float) -> str:
    """``= 0.0093`` or ``< 0.0001``: a p-value as it is reported."""
    return f"= {p:.2g}" if p >= 1e-4 else "< 0.0001"


def compare_groups(values: pd.DataFrame, value: str = "value", group: str = "group",
                   groups: Sequence[str] | None = None, what: str = "value") -> GroupTest:
    """Test whether the objects' ``value`` differ between groups (module docstring).

    Parameters
    ----------
    values : DataFrame
        One row per object (:func:`object_values`); objects without a group ("") and NaN
        values are left out.
    groups : sequence of str, optional
        The groups compared, in this order (default: every group, sorted).
    what : str
        What the values are, in words (:func:`value_words`).

    Raises
    ------
    InputError
        Fewer than two groups with at least two values each.
    """
    from scipy.stats import kruskal, mannwhitneyu

    ok = values[group].astype(str).str.strip().ne("") & np.isfinite(
        values[value].to_numpy(float))
    data = values.loc[ok]
    names = list(groups) if groups is not None else sorted(data[group].astype(str).unique())
    samples = {g: data.loc[data[group].astype(str) == g, value].to_numpy(float)
               for g in names}
    small = [g for g, v in samples.items() if len(v) < 2]
    samples = {g: v for g, v in samples.items() if len(v) >= 2}
    if len(samples) < 2:
        raise InputError(
            f"comparing groups needs two groups with at least two objects each; got "
            f"{len(samples)}" + (f" (too few objects in {', '.join(small)})" if small else ""))
    names = list(samples)
    summary = pd.DataFrame({"group": names, "n": [len(samples[g]) for g in names],
                            "median": [float(np.median(samples[g])) for g in names],
                            "q1": [float(np.percentile(samples[g], 25)) for g in names],
                            "q3": [float(np.percentile(samples[g], 75)) for g in names]})
    pairs = []
    for i, a in enumerate(names):
        for b in names[i + 1:]:
            u, p = mannwhitneyu(samples[a], samples[b], alternative="two-sided")
            pairs.append({"first": a, "second": b, "U": float(u), "p_value": float(p),
                          "effect_size": rank_biserial(samples[a], samples[b]),
                          "median_first": float(np.median(samples[a])),
                          "median_second": float(np.median(samples[b])),
                          "n_first": len(samples[a]), "n_second": len(samples[b])})
    pairs = pd.DataFrame(pairs)
    pairs["p_holm"] = holm(pairs["p_value"].to_numpy())
    if len(names) == 2:
        first = pairs.iloc[0]
        overall = {"test": "Mann-Whitney U", "statistic": float(first["U"]),
                   "p_value": float(first["p_value"]),
                   "effect_size": float(first["effect_size"]),
                   "effect_measure": "rank-biserial correlation"}
    else:
        h, p = kruskal(*samples.values())
        n = sum(len(v) for v in samples.values())
        overall = {"test": "Kruskal-Wallis", "statistic": float(h), "p_value": float(p),
                   "effect_size": float(h / (n - 1)), "effect_measure": "epsilon squared"}
    return GroupTest(summary, overall, pairs, what)


def rank_biserial(a: np.ndarray, b: np.ndarray) -> float:
    """The share of pairs (one value of ``a``, one of ``b``) where ``a``'s is larger, minus
    the share where it is smaller: from −1 (all of ``b`` larger) to 1.

    Examples
    --------
    >>> rank_biserial(np.array([3.0, 4.0]), np.array([1.0, 2.0, 3.0]))
    0.8333333333333334
    """
    diff = np.subtract.outer(np.asarray(a, float), np.asarray(b, float))
    return float((np.sum(diff > 0) - np.sum(diff < 0)) / diff.size)


def holm(p: np.ndarray) -> np.ndarray:
    """Holm's step-down adjusted p-values of ``p`` (each at most 1, never below an earlier
    one in increasing order).

    Examples
    --------
    >>> holm(np.array([0.01, 0.04, 0.03])).tolist()
    [0.03, 0.06, 0.06]
    """
    p = np.asarray(p, float)
    order = np.argsort(p, kind="stable")
    m = len(p)
    adjusted = np.minimum(1.0, np.maximum.accumulate((m - np.arange(m)) * p[order]))
    out = np.empty(m)
    out[order] = adjusted
    return out
