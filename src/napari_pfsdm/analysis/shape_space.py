"""A shape space as a fitted model: the PCA of one collection, applied to others.

:func:`napari_pfsdm.analysis.reduction.pca_scores` computes the PCA of one table. Comparing
movies needs the same axes for all of them: :class:`ShapePCA` is fitted on a reference (a
control movie, a saved table) and projects any other table into that space (``transform``),
with scikit-learn's ``fit`` / ``transform`` and the same components and signs as
``pca_scores`` on the reference. Its loadings read as a ring × harmonic map
(:meth:`ShapePCA.loadings`), and :func:`shape_modes` picks the real objects that sit at
-2σ … +2σ along a component (the "shape modes" of VAMPIRE, Momocs' morphospace).

The features can first have the classic measures regressed out (``regress_out``): the first
component of what is left is a shape difference those numbers do not already give.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import pandas as pd

from ..core.params import OPTIONS, SELECTION_OPTIONS
from ..core.table_options import table_options
from ..core.table_schema import pc_column
from ..errors import InputError
from .tables import embeddings_from_table, weighted_features

__all__ = ["ShapePCA", "shape_modes", "HARMONIC_WORDS"]

#: What each Fourier harmonic of a ring describes, in words (harmonic 0 … 4).
HARMONIC_WORDS = ("thickness", "off-centre", "elongation", "triangularity", "squareness")

#: The options two tables must share to live in one shape space: the method's (core.params,
#: without those that only choose which objects are measured) and the objects' dimension, not
#: the run's bookkeeping such as ``intensity_weight``.
_METHOD_KEYS = tuple(o.name for o in OPTIONS if o.name not in SELECTION_OPTIONS) + ("ndim",)


def _method_options(table: pd.DataFrame) -> dict:
    opts = table_options(table)
    return {k: opts[k] for k in _METHOD_KEYS if k in opts}


class ShapePCA:
    """PCA of PF-SDM features as a model fitted on one table and applied to others.

    Parameters
    ----------
    n_components : int
        Components kept (fewer when the reference has fewer rows or features).
    channel : {"shape", "intensity"}
    standardize : bool
        Give every feature unit variance (the paper's plots) instead of the PF-SDM weights
        (Euclidean distances in the weighted space are the magnitude distances).
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
        self.n_components = n_components
        self.channel = channel
        self.standardize = standardize
        self.regress_out = tuple(regress_out or ())

    # ------------------------------------------------------------------ features
    def _features(self, table: pd.DataFrame) -> tuple[np.ndarray, np.ndarray]:
        """(features of the measured rows, mask of those rows in the table)."""
        ok = (table["error"].fillna("").astype(str).eq("").to_numpy(copy=True)
              if "error" in table.columns else np.ones(len(table), bool))
        if self.standardize:
            x = embeddings_from_table(table, self.channel)[0].reshape(len(table), -1)
        else:
            x = weighted_features(table, channel=self.channel)
        ok &= np.isfinite(x).all(axis=1)
        if self.regress_out:
            missing = [c for c in self.regress_out if c not in table.columns]
            if missing:
                raise InputError(f"the table has no {', '.join(missing)} column(s) to regress "
                                 "out; measure it again with this version of napari-pfsdm")
            ok &= np.isfinite(table[list(self.regress_out)].to_numpy(float)).all(axis=1)
        return x[ok], ok

    def _covariates(self, table: pd.DataFrame, ok: np.ndarray) -> np.ndarray:
        c = table.loc[ok, list(self.regress_out)].to_numpy(float)
        return np.column_stack([np.ones(len(c)), (c - self.covariate_mean_)
                                / self.covariate_scale_])

    # ---------------------------------------------------------------------- fit
    def fit(self, table: pd.DataFrame, y=None) -> ShapePCA:
        """Fit the components on ``table`` (its rows without features are left out)."""
        x, ok = self._features(table)
        if len(x) < 2:
            raise InputError("a shape space needs at least two measured objects")
        self.options_ = _method_options(table)
        if self.regress_out:
            c = table.loc[ok, list(self.regress_out)].to_numpy(float)
            self.covariate_mean_ = c.mean(axis=0)
            sd = c.std(axis=0)
            self.covariate_scale_ = np.where(sd > 0, sd, 1.0)
            design = self._covariates(table, ok)
            self.coef_ = np.linalg.lstsq(design, x, rcond=None)[0]
            x = x - design @ self.coef_
        self.mean_ = x.mean(axis=0)
        xc = x - self.mean_
        if self.standardize:
            sd = xc.std(axis=0)
            self.scale_ = np.where(sd > 0, sd, 1.0)
        else:
            self.scale_ = np.ones(x.shape[1])
        xc = xc / self.scale_
        _u, s, vt = np.linalg.svd(xc, full_matrices=False)
        signs = np.sign(vt[np.arange(len(vt)), np.abs(vt).argmax(axis=1)])
        signs[signs == 0] = 1
        k = int(min(self.n_components, xc.shape[0], xc.shape[1]))
        self.components_ = (vt * signs[:, None])[:k]
        var = s**2
        self.explained_variance_ratio_ = var[:k] / max(float(var.sum()), 1e-300)
        self.n_features_ = x.shape[1]
        self._shape = embeddings_from_table(table.iloc[:1], self.channel)[0].shape[1:]
        return self

    def _check(self, table: pd.DataFrame) -> None:
        if not hasattr(self, "components_"):
            raise InputError("fit the shape space on a reference table first")
        theirs = _method_options(table)
        differ = sorted(k for k in set(self.options_) | set(theirs)
                        if self.options_.get(k) != theirs.get(k))
        if differ:
            said = "; ".join(f"{k}: reference {self.options_.get(k)!r}, this table "
                             f"{theirs.get(k)!r}" for k in differ)
            raise InputError(
                "this table was measured with other options than the reference, so its "
                f"features are not comparable ({said}). Measure both with the same options.")

    def transform(self, table: pd.DataFrame) -> pd.DataFrame:
        """Scores of ``table``'s measured rows in the reference's space: the key columns
        (``movie``, ``frame``, ``label``, ``track_id``, ``group`` when present) and
        ``{channel}_PC1`` …, in table order."""
        self._check(table)
        x, ok = self._features(table)
        if self.regress_out:
            x = x - self._covariates(table, ok) @ self.coef_
        z = ((x - self.mean_) / self.scale_) @ self.components_.T
        keys = [c for c in ("movie", "frame", "label", "track_id", "group")
                if c in table.columns]
        scores = pd.DataFrame(table.loc[ok, keys].to_numpy(), columns=keys)
        for col in keys:
            scores[col] = scores[col].astype(table[col].dtype)
        for i in range(z.shape[1]):
            scores[pc_column(self.channel, i + 1)] = z[:, i]
        return scores

    def fit_transform(self, table: pd.DataFrame, y=None) -> pd.DataFrame:
        return self.fit(table).transform(table)

    def get_feature_names_out(self, input_features=None) -> np.ndarray:
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
        Scores with ``{channel}_PC{component}`` (:meth:`ShapePCA.transform`, ``pca_scores``).

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
