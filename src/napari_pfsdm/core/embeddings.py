"""Magnitude embeddings with their weights: what the distances compare, as arrays.

Its own module so that :mod:`.distances` (2-D and 3-D distances) and :mod:`.distances3d` (the
3-D branch) both import it without importing each other in a circle.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import InputError

__all__ = ["Embeddings"]


@dataclass(frozen=True)
class Embeddings:
    """Magnitude embeddings of n objects with the weights that make their distances PF-SDM
    distances: what a feature table holds, as arrays (``napari_pfsdm.analysis.tables`` turns a
    table into this; the core never reads a table).

    Attributes
    ----------
    shape : ndarray, shape (n, n_radii, n_fourier + 1)
        |c_n(r)| of the SDF.
    weights : ndarray, shape (n_radii,)
        Ring quadrature weights.
    mode_weights : ndarray, shape (n_fourier + 1,)
        (1 + n)^α.
    intensity : ndarray, same shape as ``shape``, optional
        |c_n(r)| of the intensity.
    outline : ndarray of complex, shape (n, 2K), optional
        The outline coefficients of the boundary term
        (:func:`napari_pfsdm.core.boundary.outline_coefficients`).
    signature : ndarray, shape (n, channels, points), optional
        The outline signatures of the elastic term
        (:func:`napari_pfsdm.core.elastic_signature.outline_signature`).
    """

    shape: np.ndarray
    weights: np.ndarray
    mode_weights: np.ndarray
    intensity: np.ndarray | None = None
    outline: np.ndarray | None = None
    signature: np.ndarray | None = None

    def channel(self, name: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        emb = self.shape if name == "shape" else self.intensity
        if emb is None:
            raise InputError("intensity_weight > 0 needs intensity embeddings.")
        return emb, self.weights, self.mode_weights
