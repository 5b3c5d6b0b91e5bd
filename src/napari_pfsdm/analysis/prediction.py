"""The late-fusion prediction protocol (docs/design.md §2.8), and :func:`predict_outcome`, which
predicts each object's group from its early frames with it.

The protocol, the paper's with one correction:

* one vector per object and channel (its features at the chosen frames, concatenated);
* per channel, standardised features and L2 logistic regression with balanced class weights
  (:func:`logistic_pipeline`, :func:`channel_model`);
* late fusion of the channels' probabilities, ``p = sum_c w_c p_c`` with weights on a grid of
  the simplex (two channels: ``alpha * p_shape + (1 - alpha) * p_intensity``) (:func:`fuse`,
  :func:`weight_grid`);
* the weights chosen *inside each training split only*: from out-of-fold predictions of an
  inner stratified k-fold CV, or for expensive models from a hold-out of the training split
  (:func:`nested_weights`, :func:`cross_validate`); never on the test split (the paper tuned
  ``alpha`` on the test split, which is optimistic);
* repeated stratified shuffle splits, 5 x 20 % test (:func:`make_splits`), scored by the
  balanced accuracy.

A model is any callable ``fit_predict(train_idx, predict_idx)`` that trains on the objects
``train_idx`` (and may read their labels only) and returns each channel's class-1
probabilities for ``predict_idx``; :func:`channel_model` is the logistic one, and the pixel
baselines of ``examples/pixel_baseline.py`` plug into the same splits.
:mod:`napari_pfsdm.analysis.classification` builds the paper's two-channel evaluation on it.

:func:`predict_outcome` runs the protocol on a feature table with a third channel, the classic
measures of the table (:mod:`napari_pfsdm.analysis.classic`), and reports beside the fusion
each channel alone (the classic measures alone is what napari-skimage-regionprops plus a
classifier would give) and chance (a balanced accuracy of 0.5). It also gives, for every
object, the probability of each group — out-of-fold for the objects whose group is known (from a
model that never saw them), from the model of all labelled objects for the others.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from itertools import product
from typing import Any

import numpy as np
import pandas as pd
from sklearn.linear_model import LogisticRegression
from sklearn.metrics import balanced_accuracy_score
from sklearn.model_selection import StratifiedKFold, StratifiedShuffleSplit
from sklearn.pipeline import Pipeline, make_pipeline
from sklearn.preprocessing import StandardScaler

from ..core.table_options import carry_options, table_options
from ..core.table_schema import has_channel
from ..errors import InputError
from .classic import REPORTER_MEASURES, SHAPE_MEASURES_2D, SHAPE_MEASURES_3D
from .tables import left_out_reasons

__all__ = [
    "CHANNELS",
    "MAX_SEED",
    "MAX_SPLITS",
    "FitPredict",
    "Fold",
    "Prediction",
    "best_weights",
    "channel_model",
    "check_seed",
    "cross_validate",
    "fuse",
    "logistic_pipeline",
    "make_splits",
    "nested_weights",
    "predict_outcome",
    "weight_grid",
]

#: The channels :func:`predict_outcome` can fuse, in display order.
CHANNELS = ("shape", "intensity", "classic")
#: Step of :func:`predict_outcome`'s grid of fusion weights (on the simplex: weights >= 0
#: summing to 1).
WEIGHT_STEP = 0.25
#: Regularisation of each channel's logistic regression (C): strong, as few objects and many
#: features are usual (1760 features per channel for ~60 training objects of the synthetic
#: gastruloids; chosen on a development seed), milder for the few classic measures.
C_FEATURES = 0.01
C_CLASSIC = 1.0
#: Points of the accuracy-against-last-frame curve, at most.
CURVE_POINTS = 6

#: ``fit_predict(train_idx, predict_idx) -> per-channel class-1 probabilities`` (a sequence of
#: arrays, or an array (n_channels, len(predict_idx))).
FitPredict = Callable[[np.ndarray, np.ndarray], Sequence[np.ndarray]]


# ------------------------------------------------------------------------------ protocol
#: Seeds from 0 to this: each split and repeat adds one to the seed, and scikit-learn takes
#: seeds below 2**32.
MAX_SEED = 2**31 - 1
#: At most this many splits in all (splits per repeat x repeats): each fits every channel's
#: model, a few tenths of a second on a laptop.
MAX_SPLITS = 10_000


def check_seed(seed: Any, what: str = "seed") -> int:
    """``seed`` as a whole number from 0 to :data:`MAX_SEED`, else :class:`InputError`."""
    if isinstance(seed, bool) or not isinstance(seed, int | np.integer) \
            or not 0 <= int(seed) <= MAX_SEED:
        raise InputError(f"{what} must be a whole number from 0 to {MAX_SEED:,}; got {seed!r}")
    return int(seed)


def make_splits(
    y: np.ndarray,
    n_splits: int = 5,
    test_size: float = 0.2,
    n_repeats: int = 3,
    seed: int = 0,
) -> list[tuple[np.ndarray, np.ndarray]]:
    """Repeated stratified shuffle splits of the objects.

    Parameters
    ----------
    y : ndarray, (n_objects,)
        Class of each object (binary).
    n_splits, test_size : int, float
        As :class:`sklearn.model_selection.StratifiedShuffleSplit` (the paper: 5, 0.2).
    n_repeats : int
        Independent repeats (seeds ``seed``, ``seed + 1``, ...).
    seed : int
        Seed of the first repeat.

    Returns
    -------
    list of (train_idx, test_idx)
        ``n_splits * n_repeats`` pairs of disjoint index arrays into ``y``.
    """
    seed = check_seed(seed)
    if not (isinstance(n_splits, int | np.integer) and isinstance(n_repeats, int | np.integer)
            and n_splits >= 1 and n_repeats >= 1 and n_splits * n_repeats <= MAX_SPLITS):
        raise InputError(f"{n_splits!r} splits per repeat x {n_repeats!r} repeats: give whole "
                         f"numbers of at least 1, at most {MAX_SPLITS:,} splits in all (each "
                         "fits every channel's model); ask for fewer")
    y = np.asarray(y)
    classes, counts = np.unique(y, return_counts=True)
    if len(classes) != 2:
        raise InputError(f"need exactly two classes to classify, got {len(classes)}.")
    if counts.min() < 2:
        raise InputError(
            f"the smaller class has {counts.min()} object(s); stratified splits need at least 2."
        )
    out = []
    for r in range(n_repeats):
        sss = StratifiedShuffleSplit(n_splits=n_splits, test_size=test_size, random_state=seed + r)
        out.extend((tr, te) for tr, te in sss.split(np.zeros(len(y)), y))
    return out


def logistic_pipeline(C: float = C_FEATURES) -> Pipeline:
    """The paper's per-channel classifier as a scikit-learn :class:`~sklearn.pipeline.Pipeline`:
    standardised features, L2 logistic regression with balanced class weights (liblinear,
    deterministic, about 7x faster than lbfgs here). Put :class:`napari_pfsdm.PFSDMTransformer`
    in front of it to classify masks.

    Examples
    --------
    >>> list(logistic_pipeline().named_steps)
    ['standardscaler', 'logisticregression']
    """
    return make_pipeline(
        StandardScaler(),
        LogisticRegression(
            C=C, class_weight="balanced", solver="liblinear", max_iter=1000, random_state=0
        ),
    )


def channel_model(xs: Sequence[np.ndarray], y: np.ndarray,
                  C: float | Sequence[float] = C_FEATURES) -> FitPredict:
    """One :func:`logistic_pipeline` per channel as a ``fit_predict``: the vectors ``xs[c]``
    (n_objects, n_features_c) of each channel, the classes ``y`` (only ``y[train_idx]`` is ever
    read), the regularisation ``C`` of all channels or of each.

    Returns
    -------
    callable
        ``fit_predict(train_idx, predict_idx)`` -> ndarray (n_channels, len(predict_idx)).
    """
    y = np.asarray(y).astype(int)
    cs = [float(C)] * len(xs) if np.ndim(C) == 0 else [float(c) for c in C]
    if len(cs) != len(xs):
        raise InputError(f"{len(xs)} channels but {len(cs)} values of C")

    def fit_predict(train_idx: np.ndarray, predict_idx: np.ndarray) -> np.ndarray:
        out = []
        for x, c in zip(xs, cs, strict=True):
            model = logistic_pipeline(c)
            model.fit(x[train_idx], y[train_idx])
            out.append(model.predict_proba(x[predict_idx])[:, 1])
        return np.stack(out)

    return fit_predict


def weight_grid(n_channels: int, step: float = WEIGHT_STEP) -> list[tuple[float, ...]]:
    """The fusion weights searched: every ``n_channels``-tuple of multiples of ``step`` that
    sums to 1, the first channel's weight growing slowest (``(0, 1), (0.25, 0.75), …``).

    Examples
    --------
    >>> weight_grid(2, 0.5)
    [(0.0, 1.0), (0.5, 0.5), (1.0, 0.0)]
    """
    steps = np.round(np.arange(0, 1 + 1e-9, step), 6)
    return [tuple(float(v) for v in w) for w in product(steps, repeat=n_channels)
            if abs(sum(w) - 1) < 1e-6]


def fuse(probas: Sequence[np.ndarray], weights: Sequence[float]) -> np.ndarray:
    """Late fusion: ``sum_c weights[c] * probas[c]``, added in channel order."""
    out = weights[0] * np.asarray(probas[0])
    for w, p in zip(weights[1:], probas[1:], strict=True):
        out = out + w * np.asarray(p)
    return out


def best_weights(probas: Sequence[np.ndarray], y: np.ndarray,
                 grid: Sequence[tuple[float, ...]]) -> tuple[float, ...]:
    """The weights of ``grid`` whose fusion has the best balanced accuracy on ``y``; ties go to
    the weights nearest equal weights (sum of absolute differences), then to the first of
    ``grid``."""
    y = np.asarray(y).astype(int)
    scores = [balanced_accuracy_score(y, (fuse(probas, w) >= 0.5).astype(int)) for w in grid]
    best = np.flatnonzero(np.isclose(scores, max(scores)))
    even = np.full(len(grid[0]), 1 / len(grid[0]))
    return grid[min(best, key=lambda i: np.abs(np.asarray(grid[i]) - even).sum())]


def nested_weights(fit_predict: FitPredict, y: np.ndarray, train: np.ndarray, *,
                   grid: Sequence[tuple[float, ...]], folds: int = 3,
                   seed: int = 0) -> tuple[float, ...]:
    """Fusion weights from out-of-fold predictions of a stratified ``folds``-fold CV inside
    ``train`` (the objects outside it are never touched); equal weights when the smaller class
    of ``train`` has fewer than two objects, or there is one channel."""
    y = np.asarray(y).astype(int)
    n_channels = len(grid[0])
    n_folds = min(folds, int(np.bincount(y[train]).min()))
    if n_folds < 2 or n_channels == 1:
        return tuple(np.full(n_channels, 1 / n_channels))
    oof = np.empty((n_channels, len(train)))
    skf = StratifiedKFold(n_splits=n_folds, shuffle=True, random_state=seed)
    for itr, iva in skf.split(np.zeros(len(train)), y[train]):
        oof[:, iva] = np.stack(fit_predict(train[itr], train[iva]))
    return best_weights(oof, y[train], grid)


@dataclass
class Fold:
    """One split of :func:`cross_validate`: its index, objects, the fusion weights chosen
    inside its training objects and each channel's probabilities on its test objects."""

    split: int
    train: np.ndarray
    test: np.ndarray
    weights: tuple[float, ...]
    probas: np.ndarray  # (n_channels, len(test))

    def fused(self) -> np.ndarray:
        return fuse(self.probas, self.weights)


def cross_validate(
    fit_predict: FitPredict,
    y: np.ndarray,
    splits: Sequence[tuple[np.ndarray, np.ndarray]],
    *,
    grid: Sequence[tuple[float, ...]],
    inner: str = "cv",
    inner_folds: int = 3,
    seed: int = 0,
    progress: Callable[[int, int], None] | None = None,
) -> list[Fold]:
    """The protocol on every split: the fusion weights chosen inside the training split, the
    channels' probabilities on the test split.

    Parameters
    ----------
    fit_predict : callable
        The model (:func:`channel_model`, a pixel baseline, …).
    y : ndarray, (n_objects,)
        Binary class of each object.
    splits : sequence of (train_idx, test_idx)
        From :func:`make_splits`.
    grid : sequence of tuples
        The fusion weights searched (:func:`weight_grid`).
    inner : {"cv", "holdout"}
        ``"cv"``: weights from out-of-fold predictions of an ``inner_folds``-fold stratified CV
        of the training split (:func:`nested_weights`, seed ``seed + split``), then the model
        refitted on the whole training split; ``"holdout"`` (for expensive models): trained
        once on 75 % of the training split, weights from the other 25 %, and the test split
        predicted by that same model.
    progress : callable(done, total), optional
        Called after each split (a worker may raise from it to stop).

    Raises
    ------
    InputError
        A split with an object in both its training and its test set; an unknown ``inner``.
    """
    if inner not in ("cv", "holdout"):
        raise InputError(f"inner must be 'cv' or 'holdout', got {inner!r}.")
    seed = check_seed(seed)
    y = np.asarray(y).astype(int)
    folds = []
    for k, (train, test) in enumerate(splits):
        train, test = np.asarray(train), np.asarray(test)
        if np.intersect1d(train, test).size:
            raise InputError(f"split {k}: an object is in both the training and the test set.")
        if inner == "cv":
            weights = nested_weights(fit_predict, y, train, grid=grid, folds=inner_folds,
                                     seed=seed + k)
            probas = np.stack(fit_predict(train, test))
        else:
            sss = StratifiedShuffleSplit(n_splits=1, test_size=0.25, random_state=seed + k)
            itr, iva = next(sss.split(np.zeros(len(train)), y[train]))
            both = np.stack(fit_predict(train[itr], np.concatenate([train[iva], test])))
            weights = best_weights(both[:, :len(iva)], y[train[iva]], grid)
            probas = both[:, len(iva):]
        folds.append(Fold(k, train, test, weights, probas))
        if progress is not None:
            progress(k + 1, len(splits))
    return folds


# ------------------------------------------------------------------------ on a table
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

    def on_rows(self, table: pd.DataFrame, object_col: str) -> pd.DataFrame:
        """``table`` (its options kept) with each row's :meth:`columns`: its object's
        probabilities (NaN for the rows of objects that were not scored)."""
        probs = self.probabilities.set_index(object_col)
        out = table.copy()
        for name in self.columns():
            out[name] = probs[name].reindex(table[object_col].to_numpy()).to_numpy()
        return carry_options(table, out)


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


def _evaluate(model: FitPredict, y, splits, seed, tick, grid) -> list[dict]:
    """Balanced accuracy of the fused model (weights from the training split) and of each
    channel alone, on every split."""
    rows = []
    for fold in cross_validate(model, y, splits, grid=grid, seed=seed, progress=tick):
        y_te = y[fold.test]
        rows.append({"split": fold.split, "method": "fused",
                     "balanced_accuracy": balanced_accuracy_score(
                         y_te, (fold.fused() >= 0.5).astype(int)),
                     "weights": fold.weights})
        for i, px in enumerate(fold.probas):
            rows.append({"split": fold.split, "method": f"channel {i}", "balanced_accuracy":
                         balanced_accuracy_score(y_te, (px >= 0.5).astype(int)),
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
    seed = check_seed(seed)  # before any work
    object_col = object_col or ("track_id" if "track_id" in table.columns else "label")
    if object_col not in table.columns:
        raise InputError(f"the table has no {object_col!r} column to name the objects")
    ok = (table["error"].fillna("").astype(str).eq("").to_numpy(copy=True)
          if "error" in table.columns else np.ones(len(table), bool))
    ok &= left_out_reasons(table, table_options(table)) == ""  # the options' choice
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

    grid = weight_grid(len(channels))
    rows = _evaluate(channel_model(xs, y, cs), y, splits, seed, tick, grid)
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
                r = _evaluate(channel_model(sub, y, cs), y, splits, seed, tick, grid)
                s = pd.DataFrame(r).query("method == 'fused'")["balanced_accuracy"]
            curve_rows.append({"last_frame": frames[j - 1], "mean": float(s.mean()),
                               "std": float(s.std(ddof=1))})
    # probabilities: out-of-fold for the labelled objects, the full model for the others
    lab_idx = np.flatnonzero(labelled)
    p = np.full(len(objects), np.nan)
    model = channel_model(xs, y, cs)
    w_all = nested_weights(model, y, np.arange(len(y)), grid=grid, seed=seed)
    n_folds = min(5, int(counts.min()))
    skf = StratifiedKFold(n_splits=max(2, n_folds), shuffle=True, random_state=seed)
    for tr, te in skf.split(np.zeros(len(y)), y):
        p[lab_idx[te]] = fuse(model(tr, te), w_all)
    rest = np.flatnonzero(~labelled)
    if len(rest):
        p[rest] = fuse(channel_model(xs_all, y_all, cs)(lab_idx, rest), w_all)
    tick()
    probabilities = pd.DataFrame({object_col: objects,
                                  probability_column(names[0]): 1 - p,
                                  probability_column(names[1]): p})
    return Prediction(groups=(names[0], names[1]), frames=list(frames), scores=scores,
                      summary=summary, curve=pd.DataFrame(curve_rows),
                      probabilities=probabilities, channels=list(channels))
