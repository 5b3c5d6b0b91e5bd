"""PF-SDM as a scikit-learn transformer: masks in, the feature table's columns out.

:class:`PFSDMTransformer` follows scikit-learn's conventions (explicit keyword parameters
stored as given, stateless ``fit``, ``transform``, ``get_feature_names_out``, ``clone``), as
ktch does for elliptic Fourier analysis, so that PF-SDM drops into a
:class:`~sklearn.pipeline.Pipeline` with a scaler and a classifier. The aligned distance
(complex spectra, all rotations) is not a feature vector: use
``napari_pfsdm.distance_matrix(results)`` as a precomputed metric for it.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
from sklearn.base import BaseEstimator, TransformerMixin

from ..core.descriptor import pfsdm
from ..core.params import OPTIONS, PFSDMParams, with_option_keywords
from ..core.table_schema import table_feature_columns
from ..errors import InputError

__all__ = ["PFSDMTransformer"]


class PFSDMTransformer(TransformerMixin, BaseEstimator):
    """Shape features of 2-D masks or 3-D volumes, one row per mask, in the feature table's
    column order.

    Parameters
    ----------
    n_fourier, n_radii, n_angles, sdf, viscosity, mapping, normalization, radii,
    ring_weighting, mode_exponent, components, min_area, sh_degree, surface_weight, ball_map
        As :func:`napari_pfsdm.pfsdm`: one keyword per
        :data:`~napari_pfsdm.core.params.OPTIONS` entry, with its default (the signature is
        generated from it). Stored as given; ``fit`` checks them.
    spacing : 3 floats, optional
        Voxel size (Z, Y, X) of 3-D masks. 3-D masks give the columns ``shape_rXX_lYY`` and
        ``surface_lYY`` (``fit`` sees whether the masks are 2-D or 3-D).
    weighted : bool
        False (default): the magnitudes |c_n(r)| as in the table's ``shape_rXX_nYY`` columns.
        True: scaled by √(ring weight) × mode weight, so that Euclidean distances between rows
        are PF-SDM (magnitude) distances (for k-NN, clustering, PCA).

    Examples
    --------
    >>> import numpy as np
    >>> yy, xx = np.mgrid[:64, :64]
    >>> disk = (yy - 32) ** 2 + (xx - 32) ** 2 < 20 ** 2
    >>> bar = (abs(yy - 32) < 8) & (abs(xx - 32) < 25)
    >>> t = PFSDMTransformer(n_fourier=4, n_radii=3)
    >>> t.fit_transform([disk, bar]).shape
    (2, 15)
    >>> list(t.get_feature_names_out()[:2])
    ['shape_r00_n00', 'shape_r00_n01']
    """

    def __init__(self, *, spacing=None, weighted: bool = False, **options: Any) -> None:
        unknown = sorted(set(options) - {o.name for o in OPTIONS})
        if unknown:
            raise TypeError(f"PFSDMTransformer got unexpected keyword argument(s) "
                            f"{', '.join(unknown)}; its parameters are "
                            f"{', '.join(self._get_param_names())}")
        for o in OPTIONS:  # stored as given (scikit-learn's rule): checked in fit
            setattr(self, o.name, options.get(o.name, o.default))
        self.spacing = spacing
        self.weighted = weighted

    # one keyword per option of the record, with its default: what get_params, set_params,
    # clone and help() read
    __init__.__signature__ = with_option_keywords(__init__)  # type: ignore[attr-defined]

    def _params(self) -> PFSDMParams:
        """The options as the core's validated record (a bad value fails in plain words)."""
        return PFSDMParams.from_options({o.name: getattr(self, o.name) for o in OPTIONS})

    def _scale(self, record: dict) -> np.ndarray:
        """√(ring weight) × mode weight per column: Euclidean = PF-SDM (magnitude) distance
        (3-D: the surface columns get √surface_weight)."""
        w = np.sqrt(np.asarray(record["weights"]))
        if record.get("ndim") == 3:
            w = np.append(w, np.sqrt(record["surface_weight"]))
        return (w[:, None] * np.asarray(record["mode_weights"])[None, :]).ravel()

    def _ndim(self, X=None) -> int:
        if X is not None and len(X):
            return 3 if np.ndim(X[0]) == 3 else 2
        return getattr(self, "ndim_", 2)

    def fit(self, X: Sequence[np.ndarray], y=None) -> PFSDMTransformer:
        """Nothing to learn (the descriptor is fixed); checks the parameters, notes whether
        the masks are 2-D or 3-D (``ndim_``) and records the output's names. Returns self."""
        self.ndim_ = self._ndim(X)
        self._params().check_dimension(self.ndim_)
        names = self.get_feature_names_out()
        self.n_features_out_ = len(names)
        return self

    def transform(self, X: Sequence[np.ndarray]) -> np.ndarray:
        """Features of each mask.

        Parameters
        ----------
        X : sequence of 2-D boolean arrays, or an array (n, Y, X)
            One object per mask.

        Returns
        -------
        ndarray, shape (n, n_radii × (n_fourier + 1))

        Raises
        ------
        ValueError
            A mask that cannot be described (empty, too small, ...): the message names its
            position.
        """
        params = self._params()
        ndim = self._ndim(X)
        options, record = params.options(), params.record(ndim)
        if ndim == 3:
            options["spacing"] = self.spacing
        rows = []
        for i, mask in enumerate(X):
            try:
                res = pfsdm(np.asarray(mask), **options)
            except ValueError as exc:
                raise InputError(f"mask {i}: {exc}") from exc
            if getattr(res, "ndim", 2) != ndim:
                raise InputError(f"mask {i} is {getattr(res, 'ndim', 2)}-D but the first is "
                                 f"{ndim}-D; give masks of one dimension.")
            rows.append(res.embedding.ravel() if ndim == 2 else
                        np.concatenate([res.embedding.ravel(), res.surface_embedding]))
        scale = self._scale(record)
        out = np.vstack(rows) if rows else np.zeros((0, len(scale)))
        return out * scale[None, :] if self.weighted else out

    def get_feature_names_out(self, input_features=None) -> np.ndarray:
        """The table's column names ``shape_rXX_nYY`` (ring-major; after fitting on 3-D masks
        ``shape_rXX_lYY`` and ``surface_lYY``), as an object array."""
        record = self._params().record(self._ndim())
        return np.asarray(table_feature_columns(record, "shape"), dtype=object)

    def __sklearn_tags__(self):
        tags = super().__sklearn_tags__()
        tags.input_tags.two_d_array = False  # a list of masks, not a feature matrix
        tags.requires_fit = False
        return tags
