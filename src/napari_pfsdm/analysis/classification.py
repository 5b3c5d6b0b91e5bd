"""The paper's classification: one outcome per object from two channels of feature
trajectories, on the late-fusion protocol of :mod:`napari_pfsdm.analysis.prediction`.

* one feature vector per object: the concatenation of its features at the chosen frames, for
  the shape (columns ``shape_*`` of a :func:`napari_pfsdm.measure` table) and for the intensity
  (columns ``intensity_*``) separately (:func:`feature_matrix`);
* the protocol's per-channel classifiers (:func:`logistic_model`), late fusion
  ``p = alpha * p_shape + (1 - alpha) * p_intensity`` (:func:`fuse`) with ``alpha`` searched on
  :data:`ALPHAS`, repeated stratified shuffle splits (:func:`make_splits`);
* accuracy and balanced accuracy, mean and standard deviation over the splits
  (:func:`evaluate`, :func:`summarize`).

The paper chose ``alpha`` to maximise the balanced accuracy *on the test split*, which is
optimistic. :func:`evaluate` reports both: ``fusion (nested)`` is the protocol's (``alpha`` from
the training split only: it never sees a test label), and ``fusion (optimistic)`` repeats the
paper's choice on the test split, labelled as such.

A model is the protocol's ``fit_predict(train_idx, predict_idx) -> (p_shape, p_intensity)``
(:data:`~napari_pfsdm.analysis.prediction.FitPredict`); the pixel baselines in
``examples/pixel_baseline.py`` plug into the same splits.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Sequence

import numpy as np
import pandas as pd
from sklearn.metrics import accuracy_score, balanced_accuracy_score

from ..core.params import PFSDMParams, as_params
from ..core.table_options import concat_tables
from ..errors import InputError
from .prediction import (
    C_FEATURES,
    FitPredict,
    best_weights,
    channel_model,
    cross_validate,
    logistic_pipeline,
    make_splits,
)

__all__ = [
    "ALPHAS",
    "FEATURE_SETS",
    "FitPredict",
    "best_alpha",
    "evaluate",
    "feature_matrix",
    "format_frames",
    "fuse",
    "logistic_model",
    "logistic_pipeline",
    "make_splits",
    "measure_movies",
    "parse_frames",
    "size_contrast_features",
    "summarize",
]

#: Grid of fusion weights searched for alpha.
ALPHAS = np.round(np.linspace(0.0, 1.0, 21), 10)
#: Rows of the result tables, in display order.
FEATURE_SETS = ("shape", "intensity", "fusion (nested)", "fusion (optimistic, test-tuned)")


#: A selection of frames given as text, with neither the movie's length nor the table's frames
#: to bound it, may name at most this many frames (a movie has fewer).
MAX_FRAMES = 1_000_000


def frame_ranges(text: str) -> list[tuple[int, int]]:
    """The inclusive ranges of frames ``"0-9"``, ``"0,2,4"`` or ``"0-4, 8"`` name, sorted and
    merged: never a list of every frame (``"0-1000000000"`` is one range).

    Examples
    --------
    >>> frame_ranges("8, 0-4,3-5")
    [(0, 5), (8, 8)]
    """
    out = []
    for part in text.replace(" ", "").split(","):
        if not part:
            continue
        lo, sep, hi = part.partition("-")
        try:
            a = int(lo)
            b = int(hi) if sep else a
        except ValueError:
            raise InputError(
                f"could not read the frame{' range' if sep else ''} {part!r}; write frames as "
                "whole numbers from 0, e.g. '0-9' or '0,3,5'."
            ) from None
        if b < a:
            raise InputError(f"frame range {part!r} is empty: write it low-high.")
        out.append((a, b))
    out.sort()
    merged: list[tuple[int, int]] = []
    for a, b in out:
        if merged and a <= merged[-1][1] + 1:
            merged[-1] = (merged[-1][0], max(merged[-1][1], b))
        else:
            merged.append((a, b))
    return merged


def _outside(ranges: list[tuple[int, int]], have: list[int]) -> list[tuple[int, int]]:
    """The parts of ``ranges`` not in the sorted frames ``have`` (time: ranges + frames)."""
    out, i = [], 0
    for a, b in ranges:
        start = a
        while i < len(have) and have[i] < a:
            i += 1
        j = i
        while j < len(have) and have[j] <= b:
            if have[j] > start:
                out.append((start, have[j] - 1))
            start = have[j] + 1
            j += 1
        if start <= b:
            out.append((start, b))
    return out


def _ranges_text(ranges: list[tuple[int, int]], limit: int = 6) -> str:
    shown = [f"{a}" if a == b else f"{a}-{b}" for a, b in ranges[:limit]]
    return ", ".join(shown) + (" …" if len(ranges) > limit else "")


def parse_frames(
    frames: str | int | Iterable[int] | None, n_frames: int | None = None, *,
    available: Iterable[int] | None = None,
) -> list[int]:
    """Frame indices from ``"0-9"``, ``"0,2,4"``, ``"0-4,8"``, an int, a sequence or None (all).

    Ranges are read as ranges (:func:`frame_ranges`): ``"0-1000000000"`` is checked against
    the movie or the table without a list of its frames being made.

    Parameters
    ----------
    frames : str, int, iterable of int or None
        The selection; ranges are inclusive (``"0-9"`` is ten frames).
    n_frames : int, optional
        Number of frames available; needed for ``None`` and used to check the selection.
    available : iterable of int, optional
        The frames there are (a table's ``frame`` column): frames asked for that are not
        among them are refused, naming them.

    Returns
    -------
    list of int
        Sorted, unique frame indices.

    Raises
    ------
    InputError
        A selection that cannot be read, that is empty, or that names frames outside the
        movie (``n_frames``) or the table (``available``).

    Examples
    --------
    >>> parse_frames("0-2", available=[0, 1, 2, 3])
    [0, 1, 2]
    >>> try:
    ...     parse_frames("0-1000000000", available=[0, 1, 2, 3])
    ... except ValueError as exc:
    ...     print(str(exc).split(" (")[0])
    frames 4-1000000000 are not in the table
    """
    if frames is None:
        if n_frames is None and available is None:
            raise InputError("frames=None means all frames, which needs n_frames.")
        ranges = [(0, int(n_frames) - 1)] if n_frames is not None else None
    elif isinstance(frames, str):
        ranges = frame_ranges(frames)
    elif isinstance(frames, int | np.integer):
        ranges = [(int(frames), int(frames))]
    else:
        ranges = []
        for f in sorted({int(f) for f in frames}):
            if ranges and f == ranges[-1][1] + 1:
                ranges[-1] = (ranges[-1][0], f)
            else:
                ranges.append((f, f))
    have = sorted({int(f) for f in available}) if available is not None else None
    if ranges is None:  # all the table's frames
        ranges = [(f, f) for f in have]
    if not ranges:
        raise InputError("no frames selected; give e.g. frames='0-9'.")
    if ranges[0][0] < 0 or (n_frames is not None and ranges[-1][1] >= n_frames):
        outside = [(a, min(b, -1)) for a, b in ranges if a < 0]
        if n_frames is not None:
            outside += [(max(a, int(n_frames)), b) for a, b in ranges if b >= n_frames]
        raise InputError(
            f"frames {_ranges_text(outside)} are outside the movie's 0-"
            f"{(n_frames or 0) - 1}; choose frames among these.")
    if have is not None:
        missing = _outside(ranges, have)
        if missing:
            one = len(missing) == 1 and missing[0][0] == missing[0][1]
            raise InputError(
                f"frame{'' if one else 's'} {_ranges_text(missing)} {'is' if one else 'are'} "
                f"not in the table (it has frames {format_frames(have)}); choose frames among "
                "these.")
        return [f for f in have if any(a <= f <= b for a, b in ranges)]
    count = sum(b - a + 1 for a, b in ranges)
    if n_frames is None and count > MAX_FRAMES:
        raise InputError(f"frames {_ranges_text(ranges)} are {count:,} frames; no movie has "
                         f"so many (at most {MAX_FRAMES:,} here): choose the frames you mean.")
    return [f for a, b in ranges for f in range(a, b + 1)]


def format_frames(frames: Iterable[int]) -> str:
    """Frames as a short text: ``[0, 1, 2, 3, 7]`` -> ``"0-3, 7"`` (the form ``--frames``
    takes).

    Examples
    --------
    >>> format_frames([0, 1, 2, 3, 7, 9, 10])
    '0-3, 7, 9-10'
    """
    vals = sorted({int(f) for f in frames})
    if not vals:
        return "(none)"
    runs, start, prev = [], vals[0], vals[0]
    for f in vals[1:] + [None]:
        if f is not None and f == prev + 1:
            prev = f
            continue
        runs.append(str(start) if start == prev else f"{start}-{prev}")
        if f is not None:
            start = prev = f
    return ", ".join(runs)


def feature_matrix(
    table: pd.DataFrame,
    channel: str,
    frames: Sequence[int] | str | None = None,
    object_col: str = "object",
) -> tuple[np.ndarray, np.ndarray]:
    """Per-object vectors: the ``{channel}_*`` features of the chosen frames, concatenated.

    Parameters
    ----------
    table : DataFrame
        A feature table with columns ``frame``, ``object_col`` and ``{channel}_...`` (e.g. from
        :func:`napari_pfsdm.measure`, with an object column added per movie).
    channel : str
        Column prefix: ``"shape"`` or ``"intensity"``.
    frames : sequence of int or str, optional
        Frames to concatenate (default: all frames in the table).
    object_col : str
        Column naming the object a row belongs to.

    Returns
    -------
    X : ndarray, (n_objects, n_frames * n_features)
        Frame-major: all features of the first chosen frame, then of the second, ...
    objects : ndarray
        The object ids, in the row order of ``X`` (sorted).
    """
    for col in ("frame", object_col):
        if col not in table.columns:
            raise InputError(f"the table has no {col!r} column; it is needed to build vectors.")
    # the features, not the classic measures beside them (``intensity_mean``, …)
    from .classic import REPORTER_MEASURES

    cols = [c for c in table.columns
            if c.startswith(f"{channel}_") and c not in REPORTER_MEASURES]
    if not cols:
        raise InputError(
            f"the table has no '{channel}_*' columns; for intensity features, measure with an "
            "intensity image."
        )
    all_frames = sorted(table["frame"].unique())
    frames = all_frames if frames is None else parse_frames(frames, available=all_frames)
    sub = table[table["frame"].isin(frames)]
    missing = sorted(set(frames) - set(sub["frame"].unique()))
    if missing:
        raise InputError(
            f"frame{'s' if len(missing) > 1 else ''} {format_frames(missing)} "
            f"{'are' if len(missing) > 1 else 'is'} not in the table: it has frames "
            f"{format_frames(all_frames)}; choose frames among these"
        )
    if sub.duplicated([object_col, "frame"]).any():
        raise InputError(
            f"some ({object_col}, frame) pairs have several rows; keep one object per "
            f"{object_col!r} and frame (e.g. select one label)."
        )
    wide = sub.pivot(index=object_col, columns="frame", values=cols)
    wide = wide.reindex(columns=pd.MultiIndex.from_product([cols, frames]))
    bad = wide.isna().any(axis=1)
    if bad.any():
        raise InputError(
            f"objects {list(wide.index[bad])[:10]} miss a frame or have NaN features "
            "(see the table's 'error' column); drop them or choose other frames."
        )
    # frame-major order: (frame, feature)
    x = wide.to_numpy(dtype=np.float64).reshape(len(wide), len(cols), len(frames))
    return x.transpose(0, 2, 1).reshape(len(wide), -1), wide.index.to_numpy()


def logistic_model(
    x_shape: np.ndarray, x_intensity: np.ndarray, y: np.ndarray, C: float = C_FEATURES
) -> FitPredict:
    """The protocol's per-channel classifiers for the shape and the intensity as a
    ``fit_predict`` for :func:`evaluate` (:func:`napari_pfsdm.analysis.prediction.channel_model`
    of the two): standardised features and L2 logistic regression with balanced class weights,
    fitted for each channel separately. Only ``y[train_idx]`` is ever read."""
    return channel_model([x_shape, x_intensity], y, C)


def _alpha_grid(alphas: np.ndarray) -> list[tuple[float, float]]:
    return [(a, 1.0 - a) for a in np.asarray(alphas, dtype=float)]


def fuse(p_shape: np.ndarray, p_intensity: np.ndarray, alpha: float) -> np.ndarray:
    """Late fusion ``alpha * p_shape + (1 - alpha) * p_intensity``."""
    return alpha * np.asarray(p_shape) + (1.0 - alpha) * np.asarray(p_intensity)


def best_alpha(
    p_shape: np.ndarray, p_intensity: np.ndarray, y: np.ndarray, alphas: np.ndarray = ALPHAS
) -> float:
    """The alpha of ``alphas`` with the best balanced accuracy on ``y`` (ties: nearest 0.5,
    then the smaller: :func:`napari_pfsdm.analysis.prediction.best_weights`)."""
    return float(best_weights((p_shape, p_intensity), y, _alpha_grid(alphas))[0])


def evaluate(
    fit_predict: FitPredict,
    y: np.ndarray,
    splits: Sequence[tuple[np.ndarray, np.ndarray]],
    *,
    inner: str = "cv",
    inner_folds: int = 3,
    alphas: np.ndarray = ALPHAS,
    seed: int = 0,
    progress: Callable[[int, int], None] | None = None,
) -> pd.DataFrame:
    """Scores of shape, intensity and both fusions on every split.

    Parameters
    ----------
    fit_predict : callable
        ``fit_predict(train_idx, predict_idx) -> (p_shape, p_intensity)``, e.g. from
        :func:`logistic_model`.
    y : ndarray, (n_objects,)
        Binary class of each object.
    splits : sequence of (train_idx, test_idx)
        From :func:`make_splits`.
    inner : {"cv", "holdout"}
        How the nested alpha is chosen inside the training split: ``"cv"`` from out-of-fold
        predictions of ``inner_folds``-fold stratified CV (then the model is refitted on the
        whole training split); ``"holdout"`` (for expensive models) trains once on 75 % of the
        training split, picks alpha on the other 25 % and predicts the test split with that
        same model.
    inner_folds : int
        Folds of the inner CV.
    alphas : ndarray
        The alpha grid.
    seed : int
        Seed of the inner splits.
    progress : callable(done, total), optional
        Called after each split.

    Returns
    -------
    DataFrame
        One row per split and feature set: ``split``, ``features`` (see ``FEATURE_SETS``),
        ``accuracy``, ``balanced_accuracy``, ``alpha`` (NaN for single channels).
    """
    y = np.asarray(y).astype(int)
    rows = []
    for fold in cross_validate(fit_predict, y, splits, grid=_alpha_grid(alphas), inner=inner,
                               inner_folds=inner_folds, seed=seed, progress=progress):
        ps, pi = fold.probas
        a_nested = float(fold.weights[0])
        y_te = y[fold.test]
        a_opt = best_alpha(ps, pi, y_te, alphas)  # the paper's choice: tuned on the test split
        preds = {
            "shape": (ps, np.nan),
            "intensity": (pi, np.nan),
            "fusion (nested)": (fold.fused(), a_nested),
            "fusion (optimistic, test-tuned)": (fuse(ps, pi, a_opt), a_opt),
        }
        for name, (p, a) in preds.items():
            yhat = (p >= 0.5).astype(int)
            rows.append(
                {
                    "split": fold.split,
                    "features": name,
                    "accuracy": accuracy_score(y_te, yhat),
                    "balanced_accuracy": balanced_accuracy_score(y_te, yhat),
                    "alpha": a,
                }
            )
    return pd.DataFrame(rows)


def summarize(scores: pd.DataFrame) -> pd.DataFrame:
    """Mean and standard deviation over splits, one row per feature set (display order)."""
    g = scores.groupby("features", sort=False)
    out = pd.DataFrame(
        {
            "accuracy_mean": g["accuracy"].mean(),
            "accuracy_std": g["accuracy"].std(ddof=1),
            "balanced_accuracy_mean": g["balanced_accuracy"].mean(),
            "balanced_accuracy_std": g["balanced_accuracy"].std(ddof=1),
            "alpha_mean": g["alpha"].mean(),
            "n_splits": g.size(),
        }
    )
    order = [f for f in FEATURE_SETS if f in out.index]
    return out.loc[order + [f for f in out.index if f not in order]]


def measure_movies(
    labels: np.ndarray,
    intensity: np.ndarray | None = None,
    frames: Sequence[int] | str | None = None,
    params: PFSDMParams | None = None,
    **options,
) -> pd.DataFrame:
    """:func:`napari_pfsdm.measure` over one-object movies, with an ``object`` column.

    Parameters
    ----------
    labels : ndarray, (n_objects, T, Y, X)
        One movie per object (as :func:`napari_pfsdm.data.gastruloids.make_gastruloids`).
    intensity : ndarray, same shape, optional
    frames : sequence of int or str, optional
        Frames to measure (default all); only these are computed.
    **options
        Passed to :func:`napari_pfsdm.measure`.

    Returns
    -------
    DataFrame
        The concatenated tables; ``object`` is the movie index.
    """
    from .features import measure

    if labels.ndim != 4:
        raise InputError(
            f"labels must be (n_objects, T, Y, X) one-object movies, got shape {labels.shape}."
        )
    if intensity is not None and intensity.shape != labels.shape:
        raise InputError(
            f"intensity has shape {intensity.shape} but labels {labels.shape}; they must match."
        )
    sel = parse_frames(frames, labels.shape[1])
    p = as_params(params, options)
    tables = []
    for i in range(labels.shape[0]):
        tab = measure(
            labels[i][sel], None if intensity is None else intensity[i][sel], params=p
        )
        tab["frame"] = np.asarray(sel)[tab["frame"].to_numpy()]
        tab.insert(0, "object", i)
        tables.append(tab)
    return concat_tables(tables, ignore_index=True)


def size_contrast_features(
    labels: np.ndarray,
    intensity: np.ndarray,
    frames: Sequence[int] | str | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Two plain numbers per frame: relative growth and reporter contrast (a reference).

    PF-SDM removes the object's size (scale invariance) and its brightness (the intensity is
    divided by the object's mean). Over a time-lapse both leave traces that can predict the
    outcome on their own; these two features measure them directly, so that a report can say
    how much of a result they explain:

    * growth: ``0.5 * log(area_t / area_first)`` for every chosen frame after the first (the
      log of the relative equivalent radius; unchanged when the whole movie is rescaled);
    * contrast: ``mean / 99th percentile`` of the intensity inside the object at every chosen
      frame (1 for a uniform reporter, small for one bright pole; unchanged by the gain).

    Parameters
    ----------
    labels, intensity : ndarray, (n_objects, T, Y, X)
        One-object movies (label > 0 is the object), as
        :func:`napari_pfsdm.data.gastruloids.make_gastruloids`.
    frames : sequence of int or str, optional
        Frames to use (default all); growth needs at least two.

    Returns
    -------
    growth : ndarray, (n_objects, n_frames - 1)
    contrast : ndarray, (n_objects, n_frames)
    """
    if labels.ndim != 4 or intensity.shape != labels.shape:
        raise InputError(
            "labels and intensity must both be (n_objects, T, Y, X) one-object movies of the "
            f"same shape; got {labels.shape} and {intensity.shape}."
        )
    sel = parse_frames(frames, labels.shape[1])
    if len(sel) < 2:
        raise InputError("growth needs at least two frames; choose e.g. frames='0-9'.")
    n = labels.shape[0]
    area = np.zeros((n, len(sel)))
    contrast = np.zeros((n, len(sel)))
    for i in range(n):
        for j, t in enumerate(sel):
            inside = labels[i, t] > 0
            if not inside.any():
                raise InputError(f"object {i} is empty at frame {t}; drop it first.")
            values = np.asarray(intensity[i, t][inside], dtype=np.float64)
            if np.isnan(values).any():
                raise InputError(
                    f"object {i} has NaN intensity at frame {t}; replace the NaNs first."
                )
            top = float(np.percentile(values, 99))
            area[i, j] = inside.sum()
            contrast[i, j] = values.mean() / top if top > 0 else 1.0
    growth = 0.5 * np.log(area[:, 1:] / area[:, :1])
    return growth, contrast
