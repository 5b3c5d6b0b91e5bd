"""The one PCA of PF-SDM feature tables: a shape space as a fitted model.

:class:`ShapePCA` is scikit-learn's :class:`~sklearn.decomposition.PCA` (full SVD) over the
measured rows of a feature table, fitted on one table and applied to any other measured with
the same options (``transform``), so that movies can be compared in the same axes. It is the
PCA of the tables (:func:`napari_pfsdm.analysis.reduction.pca_scores` is ``fit_transform`` on
one table), of ``pfsdm trajectories`` and of the napari plugin. Each component is signed so that
its largest loading is positive, which makes the scores reproducible.

Its loadings read as a ring × harmonic map (:meth:`ShapePCA.loadings`), and :func:`shape_modes`
picks the real objects that sit at -2σ … +2σ along a component (the "shape modes" of VAMPIRE,
Momocs' morphospace). The features can first have the classic measures regressed out
(``regress_out``): the first component of what is left is a shape difference those numbers do
not already give.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import pandas as pd
from sklearn.base import BaseEstimator, TransformerMixin
from sklearn.decomposition import PCA

from ..core.params import MIDLINE_OPTIONS, OPTIONS, SELECTION_OPTIONS
from ..core.table_options import table_options
from ..core.table_schema import TRACK_COLUMN, pc_column, table_ndim
from ..errors import InputError
from .tables import embeddings_from_table, left_out_reasons, weighted_features

__all__ = ["HARMONIC_WORDS", "ShapePCA", "check_same_options", "method_options", "shape_modes"]

#: What each Fourier harmonic of a ring describes, in words (harmonic 0 … 4).
HARMONIC_WORDS = ("thickness", "off-centre", "elongation", "triangularity", "squareness")

#: The columns of a table that the scores keep, when it has them.
_SCORE_KEYS = ("movie", "frame", "time", "label", TRACK_COLUMN, "group")

#: The options two tables must share to live in one shape space: the method's (core.params,
#: without those that only choose which objects are measured or how the midline is measured)
#: and the objects' dimension, not the run's bookkeeping such as ``intensity_weight``.
_METHOD_KEYS = tuple(o.name for o in OPTIONS
                     if o.name not in SELECTION_OPTIONS + MIDLINE_OPTIONS) + ("ndim",)


def method_options(table: pd.DataFrame) -> dict:
    """The options of a table that another must share to be compared with it (the method's,
    and the objects' dimension)."""
    opts = table_options(table)
    return {k: opts[k] for k in _METHOD_KEYS if k in opts}


def check_same_options(reference: dict, table: pd.DataFrame, what: str = "reference"
                       ) -> None:
    """Refuse ``table`` when its :func:`method_options` differ from ``reference``'s (another
    table's), naming each option: their features are then not comparable."""
    theirs = method_options(table)
    differ = sorted(k for k in set(reference) | set(theirs)
                    if reference.get(k) != theirs.get(k))
    if differ:
        said = "; ".join(f"{k}: {what} {reference.get(k)!r}, this table {theirs.get(k)!r}"
                         for k in differ)
        raise InputError(
            f"this table was measured with other options than the {what}, so its features are "
            f"not comparable ({said}). Measure both with the same options.")

class ShapePCA(TransformerMixin, BaseEstimator, auto_wrap_output_keys=None):
    """PCA of PF-SDM features as a model fitted on one table and applied to others.

    A scikit-learn estimator over feature tables (``get_params``, ``clone``, pipelines): the
    features of the measured rows (rows with an ``error`` or non-finite features are left out)
    go to :class:`sklearn.decomposition.PCA` (``svd_solver="full"``), weighted as the PF-SDM
    distance by default.

    Parameters
    ----------
    n_components : int
        Components kept (fewer when the reference has fewer rows or features).
    channel : {"shape", "intensity"}
    standardize : bool
        Give every feature unit variance (the paper's plots) instead of the PF-SDM weights
        (each ring scaled by the square root of its quadrature weight, each Fourier index by
        its mode weight, so that Euclidean distances are the magnitude distances,
        docs/design.md §2.6).
    regress_out : sequence of str, optional
        Columns of the table (e.g. ``("area", "circularity")``) whose linear effect is removed
        from every feature before the PCA, with the coefficients of the reference: the PCA of
        "what the classic measures do not say".

    Attributes
    ----------
    components_ : ndarray (n_components, n_features)
        Unit loading vectors, signed so that each one's largest entry is positive.
    explained_variance_ratio_ : ndarray
        Fraction of the reference's total variance along each component.
    mean_, scale_ : ndarray
        What is subtracted from and divides each feature (scale 1 unless standardised).
    pca_ : sklearn.decomposition.PCA
        The fitted PCA of the centred (and scaled) features, with scikit-learn's signs.
    options_ : dict
        The method's options of the reference table: another table must have the same.

    Examples
    --------
    >>> import numpy as np
    >>> from napari_pfsdm import measure
    >>> labels = np.zeros((4, 64, 64), int)
    >>> for t in range(4):
    ...     labels[t, 10:30, 10:30 + 4 * t] = 1
    >>> space = ShapePCA(n_components=2).fit(measure(labels))
    >>> space.transform(measure(labels[:2])).columns.tolist()
    ['frame', 'label', 'shape_PC1', 'shape_PC2']
    """

    def __init__(self, n_components: int = 5, channel: str = "shape", *,
                 standardize: bool = False, regress_out: Sequence[str] | None = None) -> None:
        # stored as given (scikit-learn's rule, which clone checks)
        self.n_components = n_components
        self.channel = channel
        self.standardize = standardize
        self.regress_out = regress_out

    # ------------------------------------------------------------------ features
    def _regressors(self) -> list[str]:
        return list(self.regress_out or ())

    def _features(self, table: pd.DataFrame) -> tuple[np.ndarray, np.ndarray]:
        """(features of the measured rows, mask of those rows in the table): not the rows with
        an error, non-finite features, or left out by the table's options
        (:func:`~napari_pfsdm.analysis.tables.left_out_reasons`)."""
        ok = (table["error"].fillna("").astype(str).eq("").to_numpy(copy=True)
              if "error" in table.columns else np.ones(len(table), bool))
        ok &= left_out_reasons(table, table_options(table)) == ""
        if self.standardize:
            x = embeddings_from_table(table, self.channel)[0].reshape(len(table), -1)
        else:
            x = weighted_features(table, channel=self.channel)
        ok &= np.isfinite(x).all(axis=1)
        covariates = self._regressors()
        if covariates:
            missing = [c for c in covariates if c not in table.columns]
            if missing:
                raise InputError(f"the table has no {', '.join(missing)} column(s) to regress "
                                 "out; measure it again with this version of napari-pfsdm")
            ok &= np.isfinite(table[covariates].to_numpy(float)).all(axis=1)
        return x[ok], ok

    def _design(self, table: pd.DataFrame, ok: np.ndarray) -> np.ndarray:
        c = table.loc[ok, self._regressors()].to_numpy(float)
        return np.column_stack([np.ones(len(c)), (c - self.covariate_mean_)
                                / self.covariate_scale_])

    def _centred(self, table: pd.DataFrame) -> tuple[np.ndarray, np.ndarray]:
        """(the measured rows' features as the PCA sees them, mask of those rows)."""
        x, ok = self._features(table)
        if self._regressors():
            x = x - self._design(table, ok) @ self.coef_
        return (x - self.mean_) / self.scale_, ok

    # ---------------------------------------------------------------------- fit
    def fit(self, table: pd.DataFrame, y=None) -> ShapePCA:
        """Fit the components on ``table`` (its rows without features are left out).

        Raises
        ------
        InputError
            Fewer than two measured rows; a column of ``regress_out`` missing.
        """
        self._fit(table)
        return self

    def fit_transform(self, table: pd.DataFrame, y=None, **fit_params) -> pd.DataFrame:
        """:meth:`fit`, then :meth:`transform` of the same table (its features read once)."""
        z, ok = self._fit(table)
        return self._scores(table, z, ok)

    def _fit(self, table: pd.DataFrame) -> tuple[np.ndarray, np.ndarray]:
        """Fit; returns the measured rows' centred features and their mask."""
        x, ok = self._features(table)
        if len(x) < 2:
            raise InputError("PCA needs at least two measured objects (rows without error)")
        self.options_ = method_options(table)
        if self._regressors():
            c = table.loc[ok, self._regressors()].to_numpy(float)
            self.covariate_mean_ = c.mean(axis=0)
            sd = c.std(axis=0)
            self.covariate_scale_ = np.where(sd > 0, sd, 1.0)
            design = self._design(table, ok)
            self.coef_ = np.linalg.lstsq(design, x, rcond=None)[0]
            x = x - design @ self.coef_
        self.mean_ = x.mean(axis=0)
        sd = (x - self.mean_).std(axis=0) if self.standardize else np.ones(x.shape[1])
        self.scale_ = np.where(sd > 0, sd, 1.0)
        z = (x - self.mean_) / self.scale_
        k = int(min(self.n_components, z.shape[0], z.shape[1]))
        from ..core.threads import one_blas_thread

        # one BLAS thread: as fast on the tables met here, and many times faster while other
        # work (the measuring processes, napari's drawing) holds a core
        with np.errstate(invalid="ignore", divide="ignore"), one_blas_thread():
            self.pca_ = PCA(n_components=k, svd_solver="full").fit(z)
        loadings = self.pca_.components_
        signs = np.sign(loadings[np.arange(k), np.abs(loadings).argmax(axis=1)])
        self.signs_ = np.where(signs == 0, 1.0, signs)
        self.components_ = loadings * self.signs_[:, None]
        ratio = self.pca_.explained_variance_ratio_
        self.explained_variance_ratio_ = np.where(np.isfinite(ratio), ratio, 0.0)
        self.n_features_ = z.shape[1]
        opts = table_options(table)  # a map's columns: harmonics 0 … n_fourier (sh_degree)
        harmonics = int(opts["sh_degree"] if table_ndim(opts) == 3 else opts["n_fourier"]) + 1
        self._shape = (self.n_features_ // harmonics, harmonics)
        return z, ok

    def _check(self, table: pd.DataFrame) -> None:
        if not hasattr(self, "components_"):
            raise InputError("fit the shape space on a reference table first")
        check_same_options(self.options_, table)


    def transform(self, table: pd.DataFrame) -> pd.DataFrame:
        """Scores of ``table``'s measured rows in the reference's space: the key columns
        (``movie``, ``frame``, ``label``, ``track_id``, ``group`` when present) and
        ``{channel}_PC1`` …, in table order."""
        self._check(table)
        return self._scores(table, *self._centred(table))

    def _scores(self, table: pd.DataFrame, z: np.ndarray, ok: np.ndarray) -> pd.DataFrame:
        scores = self.pca_.transform(z) * self.signs_ if len(z) else np.zeros(
            (0, len(self.components_)))
        rows = np.flatnonzero(ok)
        columns = {c: table[c].array[rows] for c in _SCORE_KEYS if c in table.columns}
        columns.update((pc_column(self.channel, i + 1), scores[:, i])
                       for i in range(scores.shape[1]))
        return pd.DataFrame(columns)  # its own options: none

    def get_feature_names_out(self, input_features=None) -> np.ndarray:
        """``{channel}_PC1`` …, as an object array."""
        if not hasattr(self, "components_"):
            raise InputError("fit the shape space first")
        return np.array([pc_column(self.channel, i + 1) for i in range(len(self.components_))],
                        dtype=object)

    # ----------------------------------------------------------------- reading
    def loadings(self, component: int = 1) -> np.ndarray:
        """The loading vector of ``component`` (from 1) as a ring × harmonic map,
        ``(n_rings, n_harmonics)``: rows from the centre of the disk to the outline, columns
        harmonic 0 (thickness), 1 (off-centre), 2 (elongation), …"""
        if not hasattr(self, "components_"):
            raise InputError("fit the shape space first")
        if not 1 <= component <= len(self.components_):
            raise InputError(f"component must be 1 … {len(self.components_)}, got {component}")
        return self.components_[component - 1].reshape(self._shape)


def shape_modes(scores: pd.DataFrame, component: int = 1, channel: str = "shape",
                sigmas: Sequence[float] = (-2, -1, 0, 1, 2)) -> pd.DataFrame:
    """The measured objects nearest to ``mean + s·σ`` along a component, for each ``s``.

    Parameters
    ----------
    scores : DataFrame
        Scores with ``{channel}_PC{component}`` (:meth:`ShapePCA.transform`).

    Returns
    -------
    DataFrame
        One row per ``s``: ``sigma``, ``target`` (the score aimed at), ``row`` (position in
        ``scores``), the key columns and ``score`` of the object chosen.
    """
    col = pc_column(channel, component)
    if col not in scores.columns:
        raise InputError(f"no {col} column: the PCA has fewer components")
    v = scores[col].to_numpy(float)
    mu, sd = float(v.mean()), float(v.std())
    rows = []
    for s in sigmas:
        target = mu + float(s) * sd
        i = int(np.argmin(np.abs(v - target)))
        keys = {k: scores[k].iat[i] for k in ("movie", "frame", "label") if k in scores}
        rows.append({"sigma": float(s), "target": target, "row": i, **keys, "score": v[i]})
    return pd.DataFrame(rows)
