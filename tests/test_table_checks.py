"""The table checks look at every channel asked for, the intensity's columns as much as the
shape's (napari_pfsdm.core.table_schema, analysis.tables.failed_rows, drop_failed). The
expected column sets are written out by hand from the format (docs: ring-major
``{channel}_rXX_nYY``, 3-D ``_lYY`` plus ``surface_lYY`` for the shape only)."""

from __future__ import annotations

import types
import warnings

import numpy as np
import pytest

import napari_pfsdm as pf
from napari_pfsdm.analysis.tables import failed_rows, key_rows
from napari_pfsdm.core.table_schema import (
    check_feature_table,
    has_channel,
    has_outline,
    outline_columns,
    pc_columns,
    table_feature_columns,
)
from napari_pfsdm.errors import InputError


@pytest.fixture(scope="module")
def table():
    """Two squares with a reporter: shape and intensity columns, n_fourier 2, 2 rings."""
    labels = np.zeros((40, 40), np.uint16)
    labels[4:16, 4:16] = 1
    labels[22:36, 20:34] = 2
    image = 1.0 + np.add.outer(np.arange(40.0), np.arange(40.0)) / 10
    return pf.measure(labels, image, n_fourier=2, n_radii=2)


def names(channel, n_radii=2, n_fourier=2):
    return [f"{channel}_r{r:02d}_n{n:02d}" for r in range(n_radii) for n in range(n_fourier + 1)]


def test_the_fixture_has_both_channels(table):
    assert set(names("shape")) <= set(table.columns)
    assert set(names("intensity")) <= set(table.columns)
    assert has_channel(table.columns, "intensity") and has_channel(table.columns, "shape")


def test_has_channel_answers_for_the_channel_asked():
    shape_only = names("shape")
    assert has_channel(shape_only, "shape")
    assert not has_channel(shape_only, "intensity")
    assert has_channel(names("intensity"), "intensity")


def test_check_feature_table_checks_the_intensity_columns_too(table):
    both = ("shape", "intensity")
    opts, n_radii, n_modes = check_feature_table(table, both)
    assert (n_radii, n_modes) == (2, 2)
    cut = table.drop(columns=["intensity_r01_n02"])
    cut.attrs = table.attrs
    with pytest.raises(InputError, match="misses 1 of its 6 intensity feature columns"):
        check_feature_table(cut, both)
    check_feature_table(cut, ("shape",))  # the shape alone is whole
    none = table.drop(columns=names("intensity"))
    none.attrs = table.attrs
    with pytest.raises(InputError, match="no intensity features"):
        check_feature_table(none, both)
    extra = table.assign(intensity_r02_n00=1.0)
    extra.attrs = table.attrs
    with pytest.raises(InputError, match="1 intensity feature columns more"):
        check_feature_table(extra, both)


def test_3d_columns_and_options_by_hand():
    """2 shells, degree 1: shape_r00_l00 … shape_r01_l01 and surface_l00, surface_l01; the
    intensity has no surface term. A 3-D record without its surface weight is refused."""
    opts = {"ndim": 3, "weights": [0.5, 0.5], "sh_degree": 1, "surface_weight": 1.0}
    shape = ["shape_r00_l00", "shape_r00_l01", "shape_r01_l00", "shape_r01_l01",
             "surface_l00", "surface_l01"]
    assert table_feature_columns(opts, "shape") == shape
    assert table_feature_columns(opts, "intensity") == [c.replace("shape", "intensity")
                                                        for c in shape[:4]]
    t = types.SimpleNamespace(columns=shape, attrs={"pfsdm": opts})
    assert check_feature_table(t)[1:] == (2, 1)
    no_surface = {k: v for k, v in opts.items() if k != "surface_weight"}
    t = types.SimpleNamespace(columns=shape, attrs={"pfsdm": no_surface})
    with pytest.raises(InputError, match="surface_weight"):
        check_feature_table(t)


def test_has_outline_needs_every_outline_column():
    cols = outline_columns(3)
    assert len(cols) == 12 and has_outline(cols) == 3
    assert has_outline(cols[:-1]) == 0
    assert has_outline([c for c in cols if c != "outline_n-02_im"]) == 0


def test_pc_columns_are_the_numbered_ones_only():
    cols = ["shape_PC10", "shape_PC2", "shape_PCA_note", "shape_PC1", "intensity_PC1"]
    assert pc_columns(cols, "shape") == ["shape_PC1", "shape_PC2", "shape_PC10"]


def test_a_row_without_some_intensity_features_is_failed_for_the_intensity(table):
    """Row 0 loses one intensity number (NaN): it has no complete intensity features, so it is
    failed when the intensity is asked for, not for the shape alone; drop_failed with
    intensity=True leaves it out."""
    t = table.copy()
    t.attrs = table.attrs
    t.loc[0, "intensity_r00_n01"] = np.nan
    assert failed_rows(t, ("shape",)) == []
    bad = failed_rows(t, ("shape", "intensity"))
    assert [b[:3] for b in bad] == [(0, 0, 1)]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)
        kept = pf.drop_failed(t, intensity=True)
    assert kept["label"].tolist() == [2]
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert pf.drop_failed(t)["label"].tolist() == [1, 2]


def test_key_rows_finds_each_frame_and_label_pair_or_says_minus_one():
    at_frames, at_labels = [3, 0, 0, 1, 2], [7, 7, -2, 100, 7]
    found = key_rows([0, 0, 3, 1, 2, 5, 0], [7, -2, 7, 100, 8, 7, 100], at_frames, at_labels)
    # by hand: (0, 7) → 1, (0, −2) → 2, (3, 7) → 0, (1, 100) → 3, (2, 8) and (5, 7) and
    # (0, 100) are absent (the same label in another frame, or the same frame another label)
    assert found.tolist() == [1, 2, 0, 3, -1, -1, -1]
    assert key_rows([0], [1], [], []).tolist() == [-1]
    assert key_rows([], [], at_frames, at_labels).tolist() == []
