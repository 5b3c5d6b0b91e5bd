"""The default distance and its neighbours stay the numbers recorded before the elastic term's
search changed (commit c9e5a94): the term is opt-in, and nothing of it reaches the default.

``data/default_distances_c9e5a94.npz``: the embeddings of 52 moving blobs
(``make_moving_blobs(n_objects=30, n_frames=2, size=256, radius=(10, 16), seed=7)``, measured
with the defaults), their ``distance_matrix`` and ``nearest_neighbours(k=5)`` as that commit
computed them (its ``src`` on ``PYTHONPATH``). Stored as embeddings, so that the test holds
the distances, whatever later versions measure.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

import napari_pfsdm as pf
from napari_pfsdm.core.embeddings import Embeddings

RECORDED = Path(__file__).resolve().parent / "data" / "default_distances_c9e5a94.npz"


def test_the_default_distance_and_neighbours_are_the_recorded_numbers():
    f = np.load(RECORDED)
    items = Embeddings(f["shape"], f["weights"], f["mode_weights"], outline=f["outline"])
    np.testing.assert_allclose(pf.distance_matrix(items), f["distances"], rtol=0, atol=1e-12)
    idx, dist = pf.nearest_neighbours(items, k=5)
    assert np.array_equal(idx, f["idx"])
    np.testing.assert_allclose(dist, f["dist"], rtol=0, atol=1e-12)
    assert pf.nearest_neighbours(items, k=5, method="brute").exact
