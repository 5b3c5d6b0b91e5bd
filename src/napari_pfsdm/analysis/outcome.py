"""Each object's group predicted from its features at chosen frames, for any number of groups,
on the late-fusion protocol of :mod:`napari_pfsdm.analysis.prediction`; and a model trained on
one table that predicts the objects of another (a second microscope, a new plate).

Three families of features are the protocol's channels: the shape (``shape_*``), the reporter
(``intensity_*``) and the classic measures (area, circularity, …: what
napari-skimage-regionprops plus a classifier would give). Per family a multinomial logistic
regression with balanced class weights; the families' probabilities fused with weights chosen
inside each training split by the log-loss of out-of-fold predictions (a proper score that every
object moves, steadier on a few dozen objects than an accuracy, so that the fusion does not
fall below the best family by chance). An object is one vector (its features at the frames,
concatenated), so all its frames are on one side of every split. Scores are balanced
accuracies, against chance (1 / groups), with the confusion matrix of the fused model over the
test splits.

Examples
--------
>>> import numpy as np, pandas as pd
>>> rng = np.random.default_rng(0)
>>> rows = [{"frame": 0, "label": k, "error": "", "area": 100 + 30 * (k % 3) + rng.normal(),
...          "circularity": 0.8 + rng.normal() * 0.01} for k in range(30)]
>>> table = pd.DataFrame(rows)
>>> groups = {k: "abc"[k % 3] for k in range(30)}
>>> pred = predict_outcome(table, groups, channels=["classic"], n_repeats=1, curve=False)
>>> pred.groups, round(float(pred.summary.loc["fused", "mean"]), 2)
(('a', 'b', 'c'), 1.0)
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import pandas as pd
from sklearn.metrics import balanced_accuracy_score, confusion_matrix
from sklearn.model_selection import StratifiedKFold

from ..core.table_options import carry_options, table_options
from ..core.table_schema import has_channel
from ..errors import InputError
from .classic import REPORTER_MEASURES, SHAPE_MEASURES_2D, SHAPE_MEASURES_3D
from .physical import space_unit_of
from .prediction import (
    C_FEATURES,
    channel_model,
    check_seed,
    cross_validate,
    fuse,
    logistic_pipeline,
    make_splits,
    nested_weights,
    predicted_class,
    weight_grid,
)
from .tables import left_out_reasons

__all__ = ["CHANNELS", "FAMILY_WORDS", "OutcomeModel", "Prediction", "fit_outcome",
           "predict_outcome", "probability_column"]

#: The feature families (channels) the protocol can fuse, in display order.
CHANNELS = ("shape", "intensity", "classic")
#: How each family is called where people read it.
FAMILY_WORDS = {"shape": "shape", "intensity": "reporter", "classic": "classic measures"}
#: Regularisation (C) of the classic measures' logistic regression: mild, as their few
#: features may separate groups sharply (groups of areas three spreads apart: 0.73 balanced
#: accuracy with C = 1, 0.80 with 10, 0.78 with 100, of the 0.9 of the best rule); the PF-SDM
#: families' hundreds of features keep :data:`~napari_pfsdm.analysis.prediction.C_FEATURES`.
C_CLASSIC = 10.0
#: Points of the accuracy-against-last-frame curve, at most.
CURVE_POINTS = 6
#: What the fusion weights are chosen for, inside each training split.
WEIGHT_SCORE = "log_loss"


def probability_column(group: str) -> str:
    """``p_<group>``: the column of the probability of ``group``."""
    return "p_" + "_".join(str(group).split())


@dataclass
class Prediction:
    """What :func:`predict_outcome` found.

    Attributes
    ----------
    groups : tuple of str
        The groups, in the order of the probability columns.
    frames : list of int
        The frames whose features were used.
    scores : DataFrame
        Balanced accuracy per split and method (``fused``, ``<family> alone``).
    summary : DataFrame
        Per method (``fused``, each family alone, ``chance``): ``mean`` and ``std`` of the
        balanced accuracy over the splits, ``n_splits``.
    confusion : DataFrame
        The fused model's test predictions summed over the splits: one row per true group,
        one column per predicted group (counts of object-predictions).
    curve : DataFrame
        ``last_frame``, ``mean``, ``std``: the fused balanced accuracy using the frames up to
        that one (how early the outcome can be predicted).
    probabilities : DataFrame
        One row per object: the object id column, ``group`` (its known group, "" when none),
        ``predicted`` and ``p_<group>`` for every group (out-of-fold for the objects with a
        group, from the model of all of them for the others).
    channels : list of str
        The families used.
    weights : tuple of float
        The fusion weights of the model of all labelled objects.
    object_col : str
    """

    groups: tuple[str, ...]
    frames: list[int]
    scores: pd.DataFrame
    summary: pd.DataFrame
    confusion: pd.DataFrame
    curve: pd.DataFrame
    probabilities: pd.DataFrame
    channels: list[str] = field(default_factory=list)
    weights: tuple[float, ...] = ()
    object_col: str = "object"

    def columns(self) -> list[str]:
        """The probability columns, ``p_<group>`` (spaces become underscores)."""
        return [probability_column(g) for g in self.groups]

    @property
    def n_scored(self) -> int:
        """Objects with a group, on which the scores were measured."""
        return int((self.probabilities["group"] != "").sum())

    def on_rows(self, table: pd.DataFrame, object_col: str | None = None) -> pd.DataFrame:
        """``table`` (its options kept) with each row's object's probabilities and predicted
        group (NaN and "" for the rows of objects that were not scored)."""
        object_col = object_col or self.object_col
        probs = self.probabilities.set_index(self.object_col)
        ids = _object_ids(table, object_col)
        out = table.copy()
        for name in self.columns():
            out[name] = probs[name].reindex(ids.to_numpy()).to_numpy()
        out["predicted"] = probs["predicted"].reindex(ids.to_numpy()).fillna("").to_numpy()
        return carry_options(table, out)


def _object_ids(table: pd.DataFrame, object_col: str) -> pd.Series:
    """The object ids of the rows: the column ``object_col``, or for ``"object"`` when the
    table has no such column its objects over time, keyed by movie
    (:func:`~napari_pfsdm.analysis.reduction.object_ids`)."""
    if object_col in table.columns:
        return table[object_col]
    if object_col != "object":
        raise InputError(f"the table has no {object_col!r} column to name the objects")
    from .reduction import object_ids

    return object_ids(table)


def family_columns(table: pd.DataFrame, channel: str) -> list[str]:
    """The columns of a feature family in ``table``."""
    if channel == "classic":
        names = (*SHAPE_MEASURES_2D, *SHAPE_MEASURES_3D, *REPORTER_MEASURES, "area", "volume")
        return [c for c in dict.fromkeys(names) if c in table.columns]
    return [c for c in table.columns if str(c).startswith(f"{channel}_r")]


def _vectors(table: pd.DataFrame, columns: list[str], frames: list[int], ids: pd.Series,
             objects: np.ndarray) -> np.ndarray:
    """(n_objects, n_frames × n_columns): each object's values at the frames, concatenated;
    an object missing from a frame gets that frame's mean (and so says nothing there)."""
    blocks = []
    frame = table["frame"].to_numpy()
    for f in frames:
        at = frame == f
        rows = table.loc[at, columns].set_axis(ids[at].to_numpy())
        rows = rows[~rows.index.duplicated()]
        values = rows.reindex(objects).to_numpy(float)
        mean = np.nanmean(values, axis=0) if np.isfinite(values).any() else np.zeros(
            values.shape[1])
        mean = np.where(np.isfinite(mean), mean, 0.0)
        blocks.append(np.where(np.isfinite(values), values, mean))
    return np.concatenate(blocks, axis=1)


def _usable(table: pd.DataFrame, ids: pd.Series) -> np.ndarray:
    """Rows with features that the table's options keep in shape spaces and that belong to an
    object (not ``track_id`` -1)."""
    ok = (table["error"].fillna("").astype(str).eq("").to_numpy(copy=True)
          if "error" in table.columns else np.ones(len(table), bool))
    ok &= left_out_reasons(table, table_options(table)) == ""
    if "track_id" in table.columns:
        ok &= table["track_id"].to_numpy() >= 0
    return ok & ids.notna().to_numpy()


def _group_of(groups: Mapping) -> Callable[[Any], str | None]:
    known = {k: str(v) for k, v in groups.items() if str(v).strip()}

    def group(o):  # ids given as numbers or as text
        for key in (o, str(o)):
            if key in known:
                return known[key]
        try:
            return known.get(int(o))
        except (TypeError, ValueError):
            return None

    return group


@dataclass
class _Problem:
    """A table made into the protocol's inputs."""

    table: pd.DataFrame
    ids: pd.Series
    objects: np.ndarray
    frames: list[int]
    names: list[str]
    y_all: np.ndarray  # class of each object, -1 without a group
    channels: list[str]

    @property
    def labelled(self) -> np.ndarray:
        return self.y_all >= 0

    def matrices(self, frames: list[int] | None = None) -> list[np.ndarray]:
        use = self.frames if frames is None else frames
        return [_vectors(self.table, family_columns(self.table, c), use, self.ids, self.objects)
                for c in self.channels]


def _problem(table: pd.DataFrame, groups: Mapping, frames: Sequence[int] | None,
             object_col: str, channels: Sequence[str] | None) -> _Problem:
    ids = _object_ids(table, object_col)
    ok = _usable(table, ids)
    table, ids = table.loc[ok], ids[ok]
    all_frames = sorted(int(f) for f in table["frame"].unique())
    if not all_frames:
        raise InputError("no object of the table has features to predict from")
    frames = all_frames if frames is None else sorted(int(f) for f in frames)
    missing = sorted(set(frames) - set(all_frames))
    if missing:
        raise InputError(f"frames {missing} are not in the table (it has {all_frames[0]} … "
                         f"{all_frames[-1]})")
    if not frames:
        raise InputError("choose at least one frame")
    objects = np.array(sorted(ids.unique(), key=str), dtype=object)
    group = _group_of(groups)
    group_of = [group(o) for o in objects]
    names = sorted({g for g in group_of if g is not None})
    if len(names) < 2:
        raise InputError(f"prediction needs at least two groups among the table's objects, "
                         f"got {len(names)}: {', '.join(names) or 'none'}")
    y_all = np.array([names.index(g) if g is not None else -1 for g in group_of])
    counts = np.bincount(y_all[y_all >= 0], minlength=len(names))
    if counts.min() < 2:
        small = names[int(np.argmin(counts))]
        raise InputError(f"the group '{small}' has {counts.min()} object(s) with features; "
                         "each group needs at least two")
    if channels is None:
        channels = [c for c in CHANNELS if c == "classic" or has_channel(table.columns, c)]
    channels = [c for c in channels if family_columns(table, c)]
    if not channels:
        raise InputError("the table has no features to predict from")
    return _Problem(table, ids, objects, frames, names, y_all, list(channels))


def _cs(channels: Sequence[str]) -> list[float]:
    return [C_CLASSIC if c == "classic" else C_FEATURES for c in channels]


def _proba_matrix(p: np.ndarray, k: int) -> np.ndarray:
    """Probabilities as (n, k): a two-class model gives class 1's only."""
    p = np.asarray(p)
    return np.column_stack([1 - p, p]) if p.ndim == 1 and k == 2 else p


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
    test_size: float = 0.2,
) -> Prediction:
    """Predict each object's group from its features at ``frames``.

    Parameters
    ----------
    table : DataFrame
        A feature table (:func:`napari_pfsdm.measure`), with its classic measures; of one
        movie or many (a ``movie`` column: objects are then keyed by movie).
    groups : mapping
        Object id → group (two or more groups); objects without a group are predicted only.
    frames : sequence of int, optional
        The frames whose features are used (default: all frames of the table).
    object_col : str, optional
        The object id column; default ``"object"``: the objects over time
        (:func:`~napari_pfsdm.analysis.reduction.object_ids`: ``movie/track7``,
        ``movie/3``), which ``groups`` then names.
    channels : sequence of str, optional
        Among ``"shape"``, ``"intensity"``, ``"classic"`` (default: those the table has).
    n_splits, n_repeats : int
        Stratified shuffle splits and their repeats.
    curve : bool
        Also score the fused model on the frames up to each of (at most
        :data:`CURVE_POINTS`, evenly spread) chosen frames.
    progress : callable(done, total), optional
        Called as the work goes on (a worker may raise from it to stop).
    test_size : float
        The share of the objects each split tests (default 20 %).

    Raises
    ------
    InputError
        Fewer than two groups, a group with fewer than two objects, no such frames, too few
        objects to split.
    """
    seed = check_seed(seed)  # before any work
    object_col = object_col or "object"
    prob = _problem(table, groups, frames, object_col, channels)
    lab = np.flatnonzero(prob.labelled)
    y = prob.y_all[lab]
    k = len(prob.names)
    splits = make_splits(y, n_splits=n_splits, test_size=test_size, n_repeats=n_repeats,
                         seed=seed, names=prob.names)
    n_curve = min(CURVE_POINTS, len(prob.frames)) - 1 if curve and len(prob.frames) > 1 else 0
    steps = len(splits) * (1 + n_curve) + 1
    done = [0]

    def tick(*_):
        done[0] += 1
        if progress is not None:
            progress(done[0], steps)

    grid = weight_grid(len(prob.channels))
    xs_all = prob.matrices()
    model = channel_model([x[lab] for x in xs_all], y, _cs(prob.channels))
    folds = cross_validate(model, y, splits, grid=grid, seed=seed, progress=tick,
                           score=WEIGHT_SCORE)
    scores, confusion = _scores(folds, y, prob.channels, k)
    summary = _summary(scores, prob.channels, len(splits), k)
    curve_frame = _curve(prob, lab, y, splits, grid, seed, tick, scores) if n_curve else \
        pd.DataFrame(columns=["last_frame", "mean", "std"])
    p, weights = _probabilities(prob, xs_all, lab, y, grid, seed)
    tick()
    probabilities = pd.DataFrame({object_col: prob.objects})
    probabilities["group"] = [prob.names[c] if c >= 0 else "" for c in prob.y_all]
    probabilities["predicted"] = [prob.names[c] for c in p.argmax(axis=1)]
    for j, g in enumerate(prob.names):
        probabilities[probability_column(g)] = p[:, j]
    return Prediction(groups=tuple(prob.names), frames=list(prob.frames), scores=scores,
                      summary=summary,
                      confusion=pd.DataFrame(confusion, index=pd.Index(prob.names, name="true"),
                                             columns=pd.Index(prob.names, name="predicted")),
                      curve=curve_frame, probabilities=probabilities,
                      channels=list(prob.channels), weights=weights, object_col=object_col)


def _scores(folds, y: np.ndarray, channels: list[str], k: int
            ) -> tuple[pd.DataFrame, np.ndarray]:
    """Balanced accuracy per split of the fused model and of each family alone; the fused
    model's confusion matrix summed over the splits."""
    rows = []
    confusion = np.zeros((k, k), np.int64)
    for fold in folds:
        y_te = y[fold.test]
        fused = predicted_class(fold.fused())
        confusion += confusion_matrix(y_te, fused, labels=np.arange(k))
        rows.append({"split": fold.split, "method": "fused",
                     "balanced_accuracy": balanced_accuracy_score(y_te, fused),
                     "weights": fold.weights})
        for c, px in zip(channels, fold.probas, strict=True):
            rows.append({"split": fold.split, "method": f"{c} alone", "balanced_accuracy":
                         balanced_accuracy_score(y_te, predicted_class(px)), "weights": None})
    return pd.DataFrame(rows), confusion


def _summary(scores: pd.DataFrame, channels: list[str], n_splits: int, k: int) -> pd.DataFrame:
    order = ["fused"] + [f"{c} alone" for c in channels]
    g = scores.groupby("method")["balanced_accuracy"]
    summary = pd.DataFrame({"mean": g.mean(), "std": g.std(ddof=1), "n_splits": g.size()})
    summary = summary.loc[order]
    summary.loc["chance"] = [1.0 / k, 0.0, n_splits]
    return summary


def _curve(prob: _Problem, lab, y, splits, grid, seed, tick, scores) -> pd.DataFrame:
    """The fused balanced accuracy with the frames up to each of a few last frames."""
    frames = prob.frames
    ends = np.unique(np.round(np.linspace(1, len(frames), min(CURVE_POINTS, len(frames))))
                     ).astype(int)
    rows = []
    for j in ends:
        if j == len(frames):
            s = scores[scores["method"] == "fused"]["balanced_accuracy"]
        else:
            sub = [x[lab] for x in prob.matrices(frames[:j])]
            folds = cross_validate(channel_model(sub, y, _cs(prob.channels)), y, splits,
                                   grid=grid, seed=seed, progress=tick, score=WEIGHT_SCORE)
            s = pd.Series([balanced_accuracy_score(y[f.test], predicted_class(f.fused()))
                           for f in folds])
        rows.append({"last_frame": frames[j - 1], "mean": float(s.mean()),
                     "std": float(s.std(ddof=1))})
    return pd.DataFrame(rows)


def _probabilities(prob: _Problem, xs_all, lab, y, grid, seed
                   ) -> tuple[np.ndarray, tuple[float, ...]]:
    """(n_objects, k) probabilities: out-of-fold for the labelled objects, from the model of
    all of them for the others; the fusion weights of that model."""
    k = len(prob.names)
    cs = _cs(prob.channels)
    model = channel_model([x[lab] for x in xs_all], y, cs)
    weights = nested_weights(model, y, np.arange(len(y)), grid=grid, seed=seed,
                             score=WEIGHT_SCORE)
    p = np.full((len(prob.objects), k), np.nan)
    n_folds = max(2, min(5, int(np.bincount(y).min())))
    skf = StratifiedKFold(n_splits=n_folds, shuffle=True, random_state=seed)
    for tr, te in skf.split(np.zeros(len(y)), y):
        p[lab[te]] = _proba_matrix(fuse(model(tr, te), weights), k)
    rest = np.flatnonzero(~prob.labelled)
    if len(rest):
        full = channel_model(xs_all, prob.y_all, cs)
        p[rest] = _proba_matrix(fuse(full(lab, rest), weights), k)
    return p, weights


# ------------------------------------------------------------------ one table -> another
@dataclass
class OutcomeModel:
    """A model trained on the objects of one table, to predict those of others
    (:func:`fit_outcome`)."""

    groups: tuple[str, ...]
    frames: list[int]
    channels: list[str]
    columns: list[list[str]]
    weights: tuple[float, ...]
    models: list[Any]
    options: dict
    space_unit: str | None
    pixel_sizes: dict

    def predict(self, table: pd.DataFrame, object_col: str = "object",
                say: Callable[[str], None] = lambda m: None) -> pd.DataFrame:
        """One row per object of ``table`` with features: its keys (``movie``, ``label`` or
        ``track_id`` when the table has them), ``predicted`` and ``p_<group>`` per group.

        ``table`` must be measured with the same options (refused otherwise, naming them),
        have the model's frames and columns; ``say`` receives a warning when the classic
        measures' sizes are in pixels of different (or unknown) pixel sizes."""
        from .shape_space import check_same_options

        check_same_options(self.options, table, "training table")
        self._check_sizes(table, say)
        ids = _object_ids(table, object_col)
        ok = _usable(table, ids)
        table, ids = table.loc[ok], ids[ok]
        have = set(int(f) for f in table["frame"].unique())
        absent = [f for f in self.frames if f not in have]
        if absent:
            raise InputError(f"the table has no objects in frame(s) {absent}, which the model "
                             "was trained on: predict from frames both tables have")
        lacking = sorted({c for cols in self.columns for c in cols} - set(table.columns))
        if lacking:
            raise InputError(f"the table lacks the columns {', '.join(lacking[:5])} the model "
                             "uses (measured without a reporter?)")
        objects = np.array(sorted(ids.unique(), key=str), dtype=object)
        probas = [m.predict_proba(_vectors(table, cols, self.frames, ids, objects))
                  for m, cols in zip(self.models, self.columns, strict=True)]
        p = fuse(probas, self.weights)
        out = _keys_of(table, ids, objects)
        out["predicted"] = [self.groups[i] for i in np.argmax(p, axis=1)]
        for j, g in enumerate(self.groups):
            out[probability_column(g)] = p[:, j]
        return out

    def _check_sizes(self, table: pd.DataFrame, say: Callable[[str], None]) -> None:
        if "classic" not in self.channels:
            return
        unit = space_unit_of(table)
        if unit != self.space_unit and unit and self.space_unit:
            raise InputError(f"the training table's sizes are in {self.space_unit}, this "
                             f"table's in {unit}: measure both in the same unit")
        if unit is None or self.space_unit is None:
            theirs = _pixel_sizes(table)
            same = theirs and self.pixel_sizes and {tuple(v) for v in theirs.values()} == \
                {tuple(v) for v in self.pixel_sizes.values()}
            if not same:
                say("the classic measures' sizes are in pixels "
                    + ("and the two tables' pixel sizes differ" if theirs and self.pixel_sizes
                       else "and the pixel sizes are not known")
                    + ": areas and lengths compare pixels, not micrometres. Measure both "
                    "with their pixel size (--pixel-size) to compare sizes")


def _pixel_sizes(table: pd.DataFrame) -> dict:
    record = table_options(table) or {}
    if isinstance(record.get("pixel_sizes"), Mapping):
        return dict(record["pixel_sizes"])
    return {"": record["pixel_size"]} if record.get("pixel_size") is not None else {}


def _keys_of(table: pd.DataFrame, ids: pd.Series, objects: np.ndarray) -> pd.DataFrame:
    """One row per object: its id and the key columns of its first row."""
    keys = [c for c in ("movie", "track_id", "label") if c in table.columns]
    first = table[keys].assign(object=ids.to_numpy()).drop_duplicates("object") \
        .set_index("object")
    out = pd.DataFrame({"object": objects})
    for c in keys:
        out[c] = first[c].reindex(objects).to_numpy()
    return out


def fit_outcome(table: pd.DataFrame, groups: Mapping, frames: Sequence[int] | None = None,
                *, object_col: str = "object", channels: Sequence[str] | None = None,
                seed: int = 0) -> OutcomeModel:
    """The model of all the objects of ``table`` that have a group (the fusion weights chosen
    by cross-validation among them), to predict other tables' objects
    (:meth:`OutcomeModel.predict`)."""
    seed = check_seed(seed)
    prob = _problem(table, groups, frames, object_col, channels)
    lab = np.flatnonzero(prob.labelled)
    y = prob.y_all[lab]
    xs = [x[lab] for x in prob.matrices()]
    cs = _cs(prob.channels)
    weights = nested_weights(channel_model(xs, y, cs), y, np.arange(len(y)),
                             grid=weight_grid(len(prob.channels)), seed=seed,
                             score=WEIGHT_SCORE)
    models = [logistic_pipeline(c, max(3, len(prob.names))).fit(x, y)
              for x, c in zip(xs, cs, strict=True)]
    from .shape_space import method_options

    return OutcomeModel(groups=tuple(prob.names), frames=list(prob.frames),
                        channels=list(prob.channels),
                        columns=[family_columns(prob.table, c) for c in prob.channels],
                        weights=weights, models=models, options=method_options(table),
                        space_unit=space_unit_of(table), pixel_sizes=_pixel_sizes(table))
