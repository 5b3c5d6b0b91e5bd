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

import numpy as np
from sklearn.base import BaseEstimator, TransformerMixin

from ..core.contour import DEFAULT_MIN_AREA
from ..core.descriptor import DEFAULTS, pfsdm
from ..core.params import PFSDMParams
from ..core.table_schema import feature_columns

__all__ = ["PFSDMTransformer"]


class PFSDMTransformer(TransformerMixin, BaseEstimator):
    """Shape features of 2-D masks, one row per mask, in the feature table's column order.

    Parameters
    ----------
    n_fourier, n_radii, n_angles, sdf, viscosity, mapping, normalization, radii,
    ring_weighting, mode_exponent, components, min_area
        As :func:`napari_pfsdm.pfsdm` (same defaults).
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

    def __init__(
        self,
        *,
        n_fourier: int = DEFAULTS["n_fourier"],
        n_radii: int = DEFAULTS["n_radii"],
        n_angles: int = DEFAULTS["n_angles"],
        sdf: str = DEFAULTS["sdf"],
        viscosity: float = DEFAULTS["viscosity"],
        mapping: str = DEFAULTS["mapping"],
        normalization: str = DEFAULTS["normalization"],
        radii: str = DEFAULTS["radii"],
        ring_weighting: str = DEFAULTS["ring_weighting"],
        mode_exponent: float = DEFAULTS["mode_exponent"],
        components: str = "largest",
        min_area: int = DEFAULT_MIN_AREA,
        weighted: bool = False,
    ):
        self.n_fourier = n_fourier
        self.n_radii = n_radii
        self.n_angles = n_angles
        self.sdf = sdf
        self.viscosity = viscosity
        self.mapping = mapping
        self.normalization = normalization
        self.radii = radii
        self.ring_weighting = ring_weighting
        self.mode_exponent = mode_exponent
        self.components = components
        self.min_area = min_area
        self.weighted = weighted

    def _params(self) -> PFSDMParams:
        """The options as the core's validated record (a bad value fails in plain words)."""
        params = self.get_params()
        params.pop("weighted")
        return PFSDMParams.from_options(params)

    def _scale(self, record: dict) -> np.ndarray:
        """√(ring weight) × mode weight per column: Euclidean = PF-SDM (magnitude) distance."""
        w = np.sqrt(np.asarray(record["weights"]))[:, None]
        return (w * np.asarray(record["mode_weights"])[None, :]).ravel()

    def fit(self, X: Sequence[np.ndarray], y=None) -> PFSDMTransformer:
        """Nothing to learn (the descriptor is fixed); checks the parameters and records the
        output's names. Returns self."""
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
        options, record = params.options(), params.record()
        rows = []
        for i, mask in enumerate(X):
            try:
                rows.append(pfsdm(np.asarray(mask), **options).embedding.ravel())
            except ValueError as exc:
                raise ValueError(f"mask {i}: {exc}") from exc
        scale = self._scale(record)
        out = np.vstack(rows) if rows else np.zeros((0, len(scale)))
        return out * scale[None, :] if self.weighted else out

    def get_feature_names_out(self, input_features=None) -> np.ndarray:
        """The table's column names ``shape_rXX_nYY`` (ring-major), as an object array."""
        record = self._params().record()
        return np.asarray(feature_columns(record["n_radii"], record["n_fourier"], "shape"),
                          dtype=object)

    def __sklearn_tags__(self):
        tags = super().__sklearn_tags__()
        tags.input_tags.two_d_array = False  # a list of masks, not a feature matrix
        tags.requires_fit = False
        return tags
