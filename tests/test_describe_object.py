"""describe_object (what the plugin's pictures are made from) describes an object exactly as
the run that measured it: same crop, same reporter pixels, same options."""

import numpy as np

from napari_pfsdm.analysis.features import describe_object, iter_objects
from napari_pfsdm.core.params import PFSDMParams


def test_describe_object_equals_the_runs_object_with_its_reporter():
    rng = np.random.default_rng(3)
    yy, xx = np.mgrid[:96, :128]
    labels = np.zeros((3, 96, 128), np.uint16)
    for t in range(3):
        labels[t][((yy - 40 - 3 * t) / 22) ** 2 + ((xx - 50) / 12) ** 2 < 1] = 4
        labels[t][((yy - 60) / 10) ** 2 + ((xx - 100 + t) / 18) ** 2 < 1] = 9
        labels[t][0:14, 0:20] = 2  # on the border
    reporter = rng.normal(100, 10, labels.shape) + 0.2 * xx  # a gradient across each object
    params = PFSDMParams(n_fourier=12)
    run = {(o.frame, o.label): o for o in iter_objects(labels, reporter, params=params)}
    assert len(run) == 9
    for (t, label), expected in run.items():
        got = describe_object(labels, reporter, t, label, params=params)
        assert got.bbox == expected.bbox and got.area == expected.area
        np.testing.assert_array_equal(got.result.embedding, expected.result.embedding)
        np.testing.assert_array_equal(got.result.intensity_embedding,
                                      expected.result.intensity_embedding)
