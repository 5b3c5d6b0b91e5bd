"""The late-fusion prediction protocol (docs/design.md §2.8), for two groups or more;
:mod:`napari_pfsdm.analysis.outcome` runs it on feature tables.

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

:func:`napari_pfsdm.analysis.outcome.predict_outcome` runs the protocol on a feature table,
with the classic measures as a third channel.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from itertools import product
from typing import Any

import numpy as np
from sklearn.linear_model import LogisticRegression
from sklearn.metrics import balanced_accuracy_score
from sklearn.model_selection import StratifiedKFold, StratifiedShuffleSplit
from sklearn.pipeline import Pipeline, make_pipeline
from sklearn.preprocessing import StandardScaler

from ..errors import InputError

__all__ = [
    "MAX_SEED",
    "MAX_SPLITS",
    "FitPredict",
    "Fold",
    "best_weights",
    "channel_model",
    "check_seed",
    "cross_validate",
    "fuse",
    "logistic_pipeline",
    "make_splits",
    "nested_weights",
    "log_loss_of",
    "predicted_class",
    "weight_grid",
]

#: Step of the grid of fusion weights (on the simplex: weights >= 0
#: summing to 1).
WEIGHT_STEP = 0.25
#: Regularisation of each channel's logistic regression (C): strong, as few objects and many
#: features are usual (1760 features per channel for ~60 training objects of the synthetic
#: gastruloids; chosen on a development seed), milder for the few classic measures.
C_FEATURES = 0.01

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
    names: Sequence[str] | None = None,
) -> list[tuple[np.ndarray, np.ndarray]]:
    """Repeated stratified shuffle splits of the objects.

    Parameters
    ----------
    y : ndarray, (n_objects,)
        Class of each object (two or more classes).
    n_splits, test_size : int, float
        As :class:`sklearn.model_selection.StratifiedShuffleSplit` (the paper: 5, 0.2).
    n_repeats : int
        Independent repeats (seeds ``seed``, ``seed + 1``, ...).
    seed : int
        Seed of the first repeat.
    names : sequence of str, optional
        The classes' names (class ``k`` is ``names[k]``), for messages.

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
    if len(classes) < 2:
        raise InputError(f"need at least two classes to classify, got {len(classes)}.")
    if counts.min() < 2:
        raise InputError(
            f"the smallest class has {counts.min()} object(s); stratified splits need at "
            "least 2.")
    n_test = int(np.ceil(test_size * len(y)))
    if n_test < len(classes) or len(y) - n_test < len(classes):
        counts_words = ", ".join(f"{c} {names[int(k)] if names is not None else k}"
                                 for k, c in zip(classes, counts, strict=True))
        raise InputError(
            f"{len(y)} objects ({counts_words}) are too few for a {test_size:.0%} test "
            f"split: each side of a split needs an object of every group ({n_test} would be "
            "tested). Measure more objects, or change the test size (--test-size, e.g. 0.5)")
    out = []
    for r in range(n_repeats):
        sss = StratifiedShuffleSplit(n_splits=n_splits, test_size=test_size, random_state=seed + r)
        out.extend((tr, te) for tr, te in sss.split(np.zeros(len(y)), y))
    return out


def logistic_pipeline(C: float = C_FEATURES, n_classes: int = 2) -> Pipeline:
    """The paper's per-channel classifier as a scikit-learn :class:`~sklearn.pipeline.Pipeline`:
    standardised features, L2 logistic regression with balanced class weights (two classes:
    liblinear, deterministic, about 7x faster than lbfgs here; more: the multinomial model,
    lbfgs). Put :class:`napari_pfsdm.PFSDMTransformer` in front of it to classify masks.

    Examples
    --------
    >>> list(logistic_pipeline().named_steps)
    ['standardscaler', 'logisticregression']
    """
    solver = "liblinear" if n_classes <= 2 else "lbfgs"
    return make_pipeline(
        StandardScaler(),
        LogisticRegression(
            C=C, class_weight="balanced", solver=solver, max_iter=1000, random_state=0
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
        ``fit_predict(train_idx, predict_idx)`` -> ndarray (n_channels, len(predict_idx)): the
        class-1 probabilities for two classes 0 and 1; for ``k`` > 2 classes ``0 … k - 1``,
        (n_channels, len(predict_idx), k): each class's.
    """
    y = np.asarray(y).astype(int)
    cs = [float(C)] * len(xs) if np.ndim(C) == 0 else [float(c) for c in C]
    if len(cs) != len(xs):
        raise InputError(f"{len(xs)} channels but {len(cs)} values of C")
    n_classes = int(y[y >= 0].max()) + 1 if (y >= 0).any() else 2

    def fit_predict(train_idx: np.ndarray, predict_idx: np.ndarray) -> np.ndarray:
        out = []
        for x, c in zip(xs, cs, strict=True):
            model = logistic_pipeline(c, n_classes)
            model.fit(x[train_idx], y[train_idx])
            proba = model.predict_proba(x[predict_idx])
            if n_classes <= 2:
                out.append(proba[:, 1])
                continue
            full = np.zeros((len(predict_idx), n_classes))
            full[:, model.classes_] = proba  # a class absent from training: probability 0
            out.append(full)
        return np.stack(out)

    return fit_predict


def predicted_class(p: np.ndarray) -> np.ndarray:
    """The class each object is given: class 1 where the class-1 probability is ≥ 0.5
    (two classes, ``p`` of shape (n,)), else the most probable (``p`` (n, k))."""
    p = np.asarray(p)
    return (p >= 0.5).astype(int) if p.ndim == 1 else np.argmax(p, axis=1)


def log_loss_of(p: np.ndarray, y: np.ndarray) -> float:
    """Mean negative log-probability of the true classes (probabilities clipped to
    [1e-6, 1]), each class weighted by the inverse of its count (balanced, as the models)."""
    p = np.asarray(p, float)
    y = np.asarray(y).astype(int)
    truth = np.where(y == 1, p, 1 - p) if p.ndim == 1 else p[np.arange(len(y)), y]
    weights = 1.0 / np.bincount(y)[y]
    return float(-(weights * np.log(np.clip(truth, 1e-6, 1.0))).sum() / weights.sum())


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
                 grid: Sequence[tuple[float, ...]], score: str = "balanced_accuracy"
                 ) -> tuple[float, ...]:
    """The weights of ``grid`` whose fusion scores best on ``y``.

    ``score``: ``"balanced_accuracy"`` (the highest; ties go to the weights nearest equal
    weights, sum of absolute differences, then to the first of ``grid``) or ``"log_loss"``
    (the lowest :func:`log_loss_of`, which every object's probability moves and so varies
    less from sample to sample than an accuracy of a few objects; ties as above).
    """
    y = np.asarray(y).astype(int)
    fused = [fuse(probas, w) for w in grid]
    if score == "log_loss":
        scores = [-log_loss_of(f, y) for f in fused]
    else:
        scores = [balanced_accuracy_score(y, predicted_class(f)) for f in fused]
    best = np.flatnonzero(np.isclose(scores, max(scores)))
    even = np.full(len(grid[0]), 1 / len(grid[0]))
    return grid[min(best, key=lambda i: np.abs(np.asarray(grid[i]) - even).sum())]


def nested_weights(fit_predict: FitPredict, y: np.ndarray, train: np.ndarray, *,
                   grid: Sequence[tuple[float, ...]], folds: int = 3,
                   seed: int = 0, score: str = "balanced_accuracy") -> tuple[float, ...]:
    """Fusion weights from out-of-fold predictions of a stratified ``folds``-fold CV inside
    ``train`` (the objects outside it are never touched), scored by ``score``
    (:func:`best_weights`); equal weights when the smallest class of ``train`` has fewer than
    two objects, or there is one channel."""
    y = np.asarray(y).astype(int)
    n_channels = len(grid[0])
    present = np.bincount(y[train])
    n_folds = min(folds, int(present[present > 0].min()))
    if n_folds < 2 or n_channels == 1:
        return tuple(np.full(n_channels, 1 / n_channels))
    oof = None
    skf = StratifiedKFold(n_splits=n_folds, shuffle=True, random_state=seed)
    for itr, iva in skf.split(np.zeros(len(train)), y[train]):
        part = np.stack(fit_predict(train[itr], train[iva]))
        if oof is None:
            oof = np.empty((n_channels, len(train), *part.shape[2:]))
        oof[:, iva] = part
    return best_weights(oof, y[train], grid, score)


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
    score: str = "balanced_accuracy",
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
    score : {"balanced_accuracy", "log_loss"}
        What the fusion weights are chosen for (:func:`best_weights`).

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
                                     seed=seed + k, score=score)
            probas = np.stack(fit_predict(train, test))
        else:
            sss = StratifiedShuffleSplit(n_splits=1, test_size=0.25, random_state=seed + k)
            itr, iva = next(sss.split(np.zeros(len(train)), y[train]))
            both = np.stack(fit_predict(train[itr], np.concatenate([train[iva], test])))
            weights = best_weights(both[:, :len(iva)], y[train[iva]], grid, score)
            probas = both[:, len(iva):]
        folds.append(Fold(k, train, test, weights, probas))
        if progress is not None:
            progress(k + 1, len(splits))
    return folds
