"""Predict each object's outcome (a group) from its early frames: shape, reporter and classic
measures, fused late, scored on repeated stratified splits.

The protocol is :mod:`napari_pfsdm.analysis.classification`'s (one vector per object: its
features at the chosen frames, concatenated; standardised features and balanced logistic
regression per channel; repeated stratified shuffle splits) with a third channel, the classic
measures of the table (:mod:`napari_pfsdm.analysis.classic`), and the fusion weights of the
channels chosen *inside each training split only* (out-of-fold predictions of an inner
stratified CV), never on the test split. Reported beside it: each channel alone (the classic
measures alone is what napari-skimage-regionprops plus a classifier would give) and chance
(a balanced accuracy of 0.5). :func:`predict_outcome` also gives, for every object, the
probability of each group — out-of-fold for the objects whose group is known (from a model
that never saw them), from the model of all labelled objects for the others.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from itertools import product

import numpy as np
import pandas as pd
from sklearn.metrics import balanced_accuracy_score
from sklearn.model_selection import StratifiedKFold

from ..core.table_schema import has_channel
from ..errors import InputError
from .classic import REPORTER_MEASURES, SHAPE_MEASURES_2D, SHAPE_MEASURES_3D
from .classification import logistic_pipeline, make_splits

__all__ = ["Prediction", "predict_outcome", "CHANNELS"]

#: The channels that can be fused, in display order.
CHANNELS = ("shape", "intensity", "classic")
#: Step of the grid of fusion weights (on the simplex: weights ≥ 0 summing to 1).
WEIGHT_STEP = 0.25
#: Regularisation of each channel's logistic regression (C): strong, as few objects and many
#: features are usual (classification.logistic_model's choice), milder for the few classic
#: measures.
C_FEATURES = 0.01
C_CLASSIC = 1.0
#: Points of the accuracy-against-last-frame curve, at most.
CURVE_POINTS = 6


@dataclass
class Prediction:
    """What :func:`predict_outcome` found.

    Attributes
    ----------
    groups : (str, str)
        The two groups; probabilities are given for both (``p_<group>`` columns).
    frames : list of int
        The frames whose features were used.
    scores : DataFrame
        Balanced accuracy per split and method (``fused``, each channel alone).
    summary : DataFrame
        Mean and standard deviation of the balanced accuracy per method, with ``chance``.
    curve : DataFrame
        ``last_frame``, ``mean``, ``std``: the fused model's balanced accuracy using the frames
        up to that one (how early the outcome can be predicted).
    probabilities : DataFrame
        One row per object: the object id column and ``p_<group>`` for both groups.
    channels : list of str
        The channels used.
    """

    groups: tuple[str, str]
    frames: list[int]
    scores: pd.DataFrame
    summary: pd.DataFrame
    curve: pd.DataFrame
    probabilities: pd.DataFrame
    channels: list[str] = field(default_factory=list)

    def columns(self) -> list[str]:
        """The probability columns, ``p_<group>`` (spaces become underscores)."""
        return [probability_column(g) for g in self.groups]


def probability_column(group: str) -> str:
    """``p_<group>``: the column of the probability of ``group``."""
    return "p_" + "_".join(str(group).split())


def _channel_columns(table: pd.DataFrame, channel: str) -> list[str]:
    if channel == "classic":
        names = (*SHAPE_MEASURES_2D, *SHAPE_MEASURES_3D, *REPORTER_MEASURES, "area", "volume")
        return [c for c in dict.fromkeys(names) if c in table.columns]
    return [c for c in table.columns if str(c).startswith(f"{channel}_r")]


def _vectors(table: pd.DataFrame, columns: list[str], frames: list[int], object_col: str,
             objects: np.ndarray) -> np.ndarray:
    """(n_objects, n_frames × n_columns): each object's values at the frames, concatenated;
    an object missing from a frame gets that frame's mean (and so says nothing there)."""
    blocks = []
    for f in frames:
        rows = table[table["frame"] == f].drop_duplicates(object_col).set_index(object_col)
        values = rows.reindex(objects)[columns].to_numpy(float)
        mean = np.nanmean(values, axis=0) if np.isfinite(values).any() else np.zeros(
            values.shape[1])
        mean = np.where(np.isfinite(mean), mean, 0.0)
        values = np.where(np.isfinite(values), values, mean)
        blocks.append(values)
    return np.concatenate(blocks, axis=1)


def _weights(n: int) -> list[tuple[float, ...]]:
    """Fusion weights on the simplex (grid of :data:`WEIGHT_STEP`)."""
    steps = np.round(np.arange(0, 1 + 1e-9, WEIGHT_STEP), 6)
    return [w for w in product(steps, repeat=n) if abs(sum(w) - 1) < 1e-6]


def _fit_proba(x: np.ndarray, y: np.ndarray, tr: np.ndarray, pr: np.ndarray,
               c: float) -> np.ndarray:
    model = logistic_pipeline(c)
    model.fit(x[tr], y[tr])
    return model.predict_proba(x[pr])[:, 1]


def _channel_probas(xs: list[np.ndarray], cs: list[float], y, tr, pr) -> np.ndarray:
    return np.stack([_fit_proba(x, y, tr, pr, c) for x, c in zip(xs, cs, strict=True)])


def _inner_weights(xs, cs, y, train, seed: int) -> tuple[float, ...]:
    """Fusion weights from out-of-fold predictions inside ``train`` (never the test split)."""
    grid = _weights(len(xs))
    n_folds = min(3, int(np.bincount(y[train]).min()))
    if n_folds < 2 or len(xs) == 1:
        return tuple(np.full(len(xs), 1 / len(xs)))
    oof = np.empty((len(xs), len(train)))
    skf = StratifiedKFold(n_splits=n_folds, shuffle=True, random_state=seed)
    for itr, iva in skf.split(np.zeros(len(train)), y[train]):
        oof[:, iva] = _channel_probas(xs, cs, y, train[itr], train[iva])
    scores = [balanced_accuracy_score(y[train], (np.dot(w, oof) >= 0.5).astype(int))
              for w in grid]
    best = np.flatnonzero(np.isclose(scores, max(scores)))
    even = np.full(len(xs), 1 / len(xs))
    return grid[min(best, key=lambda i: np.abs(np.asarray(grid[i]) - even).sum())]


def _evaluate(xs, cs, y, splits, seed, stop) -> list[dict]:
    """Balanced accuracy of the fused model (weights from the training split) and of each
    channel alone, on every split."""
    rows = []
    for k, (train, test) in enumerate(splits):
        if stop is not None:
            stop(k, len(splits))
        w = _inner_weights(xs, cs, y, train, seed + k)
        p = _channel_probas(xs, cs, y, train, test)
        rows.append({"split": k, "method": "fused",
                     "balanced_accuracy": balanced_accuracy_score(
                         y[test], (np.dot(w, p) >= 0.5).astype(int)),
                     "weights": w})
        for i, px in enumerate(p):
            rows.append({"split": k, "method": f"channel {i}", "balanced_accuracy":
                         balanced_accuracy_score(y[test], (px >= 0.5).astype(int)),
                         "weights": None})
    return rows


def predict_outcome(
    table: pd.DataFrame,
    groups: Mapping,
    frames: Sequence[int] | None = None,
    *,
    object_col: str | None = None,
    channels: Sequence[str] | None = None,
    n_splits: int = 5,
    n_repeats: int = 2,
    curve: bool = True,
    seed: int = 0,
    progress: Callable[[int, int], None] | None = None,
) -> Prediction:
    """Predict each object's group from its features at ``frames``.

    Parameters
    ----------
    table : DataFrame
        A feature table (:func:`napari_pfsdm.measure`), with its classic measures.
    groups : mapping
        Object id → group (exactly two groups); objects without a group are predicted only.
    frames : sequence of int, optional
        The frames whose features are used (default: all frames of the table).
    object_col : str, optional
        The object id column: ``track_id`` when the table has one, else ``label``.
    channels : sequence of str, optional
        Among ``"shape"``, ``"intensity"``, ``"classic"`` (default: those the table has).
    n_splits, n_repeats : int
        Stratified shuffle splits (20 % test each) and their repeats.
    curve : bool
        Also score the fused model on the frames up to each of (at most
        :data:`CURVE_POINTS`, evenly spread) chosen frames.
    progress : callable(done, total), optional
        Called as the work goes on (a worker may raise from it to stop).

    Raises
    ------
    InputError
        Not two groups, a group with fewer than two objects, no such frames.
    """
    object_col = object_col or ("track_id" if "track_id" in table.columns else "label")
    if object_col not in table.columns:
        raise InputError(f"the table has no {object_col!r} column to name the objects")
    ok = (table["error"].fillna("").astype(str).eq("").to_numpy(copy=True)
          if "error" in table.columns else np.ones(len(table), bool))
    ids = table[object_col]
    if pd.api.types.is_numeric_dtype(ids):  # track_id -1: rows no track reaches
        ok &= ids.to_numpy() >= 0
    table = table.loc[ok]
    all_frames = sorted(int(f) for f in table["frame"].unique())
    frames = all_frames if frames is None else sorted(int(f) for f in frames)
    missing = sorted(set(frames) - set(all_frames))
    if missing:
        raise InputError(f"frames {missing} are not in the table (it has {all_frames[0]} … "
                         f"{all_frames[-1]})")
    if not frames:
        raise InputError("choose at least one frame")
    known = {k: str(v) for k, v in groups.items() if str(v).strip()}
    names = sorted(set(known.values()))
    if len(names) != 2:
        raise InputError(f"prediction needs exactly two groups, got {len(names)}: "
                         f"{', '.join(names) or 'none'}")
    objects = np.array(sorted(table[object_col].unique()))
    def group(o):  # ids given as numbers or as text
        for key in (o, str(o)):
            if key in known:
                return known[key]
        try:
            return known.get(int(o))
        except (TypeError, ValueError):
            return None

    group_of = [group(o) for o in objects]
    labelled = np.array([g is not None for g in group_of])
    y_all = np.array([names.index(g) if g is not None else -1 for g in group_of])
    y = y_all[labelled]
    counts = np.bincount(y, minlength=2)
    if counts.min() < 2:
        raise InputError(f"the group '{names[int(np.argmin(counts))]}' has "
                         f"{counts.min()} object(s) with features; each needs at least two")
    if channels is None:
        channels = [c for c in CHANNELS if c == "classic" or has_channel(table.columns, c)]
    channels = [c for c in channels if _channel_columns(table, c)]
    if not channels:
        raise InputError("the table has no features to predict from")
    cs = [C_CLASSIC if c == "classic" else C_FEATURES for c in channels]

    def matrices(use_frames):
        return [_vectors(table, _channel_columns(table, c), use_frames, object_col, objects)
                for c in channels]

    xs_all = matrices(frames)
    xs = [x[labelled] for x in xs_all]
    splits = make_splits(y, n_splits=n_splits, test_size=0.2, n_repeats=n_repeats, seed=seed)
    n_curve = min(CURVE_POINTS, len(frames)) - 1 if curve and len(frames) > 1 else 0
    steps = len(splits) * (1 + n_curve) + 1
    done = [0]

    def tick(*_):
        done[0] += 1
        if progress is not None:
            progress(done[0], steps)

    rows = _evaluate(xs, cs, y, splits, seed, tick)
    scores = pd.DataFrame(rows)
    scores["method"] = scores["method"].map(
        lambda m: m if m == "fused" else f"{channels[int(m.split()[1])]} alone")
    order = ["fused"] + [f"{c} alone" for c in channels]
    g = scores.groupby("method")["balanced_accuracy"]
    summary = pd.DataFrame({"mean": g.mean(), "std": g.std(ddof=1), "n_splits": g.size()})
    summary = summary.loc[order]
    summary.loc["chance"] = [0.5, 0.0, len(splits)]
    curve_rows = []
    if curve and len(frames) > 1:
        # at most CURVE_POINTS last frames, evenly spread (each point is a whole evaluation)
        ends = np.unique(np.round(np.linspace(1, len(frames), min(CURVE_POINTS, len(frames))))
                         ).astype(int)
        for j in ends:
            if j == len(frames):
                s = scores[scores["method"] == "fused"]["balanced_accuracy"]
            else:
                sub = [x[labelled] for x in matrices(frames[:j])]
                r = _evaluate(sub, cs, y, splits, seed, tick)
                s = pd.DataFrame(r).query("method == 'fused'")["balanced_accuracy"]
            curve_rows.append({"last_frame": frames[j - 1], "mean": float(s.mean()),
                               "std": float(s.std(ddof=1))})
    # probabilities: out-of-fold for the labelled objects, the full model for the others
    lab_idx = np.flatnonzero(labelled)
    p = np.full(len(objects), np.nan)
    w_all = _inner_weights(xs, cs, y, np.arange(len(y)), seed)
    n_folds = min(5, int(counts.min()))
    skf = StratifiedKFold(n_splits=max(2, n_folds), shuffle=True, random_state=seed)
    for tr, te in skf.split(np.zeros(len(y)), y):
        p[lab_idx[te]] = np.dot(w_all, _channel_probas(xs, cs, y, tr, te))
    rest = np.flatnonzero(~labelled)
    if len(rest):
        y_full = y_all.copy()
        probas = np.stack([_fit_proba(x, y_full, lab_idx, rest, c)
                           for x, c in zip(xs_all, cs, strict=True)])
        p[rest] = np.dot(w_all, probas)
    tick()
    probabilities = pd.DataFrame({object_col: objects,
                                  probability_column(names[0]): 1 - p,
                                  probability_column(names[1]): p})
    return Prediction(groups=(names[0], names[1]), frames=list(frames), scores=scores,
                      summary=summary, curve=pd.DataFrame(curve_rows),
                      probabilities=probabilities, channels=list(channels))
