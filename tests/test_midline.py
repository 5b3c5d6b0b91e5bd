"""The object's own axis (core.midline): closed forms and scikit-image's numbers."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
from skimage.measure import regionprops

from napari_pfsdm.core.descriptor import pfsdm
from napari_pfsdm.core.midline import midline, midline_columns
from napari_pfsdm.data.shapes import bent_capsule_mask


def ellipse(a: float, b: float, degrees: float = 0.0, margin: int = 10):
    """Mask of an ellipse of half-axes ``a`` (along +x, turned by ``degrees`` counter-clockwise
    as shown) and ``b``, and the image's x (columns) and up (−rows) coordinates from its
    centre."""
    n = int(2 * max(a, b)) + 2 * margin + 1
    yy, xx = np.mgrid[:n, :n] - n // 2
    up = -yy.astype(float)
    th = np.radians(degrees)
    u = xx * np.cos(th) + up * np.sin(th)
    v = -xx * np.sin(th) + up * np.cos(th)
    return (u / a) ** 2 + (v / b) ** 2 <= 1, xx.astype(float), up


def chord_bin_means(a: float, b: float, bins: int) -> np.ndarray:
    """Exact mean of the ellipse's chord 2b·√(1 − (x/a)²) over ``bins`` equal pieces of its
    major axis: ∫ 2b√(1 − s²) ds = b (s√(1 − s²) + arcsin s)."""
    s = np.linspace(-1, 1, bins + 1)
    big = b * (s * np.sqrt(1 - s**2) + np.arcsin(s))
    return np.diff(big) / np.diff(s)


@pytest.mark.parametrize("degrees", [0.0, 30.0, 90.0])
def test_an_ellipse_midline_is_its_major_axis_and_its_widths_the_chords(degrees):
    a, b = 80.0, 30.0
    mask, _, _ = ellipse(a, b, degrees)
    m = midline(pfsdm(mask), bins=10)
    props = regionprops(mask.astype(np.uint8))[0]
    assert abs(m.length - 2 * a) < 1.0
    assert abs(m.length - props.axis_major_length) < 1.0
    assert abs(m.width_max - 2 * b) < 1.0
    assert abs(m.width_max - props.axis_minor_length) < 1.0
    assert abs(m.width_mean - np.pi * b / 2) < 0.5  # = area / length
    assert np.abs(m.width_bins - chord_bin_means(a, b, 10)).max() < 1.0
    assert m.width[0] == m.width[-1] == 0.0
    # the ends lie on the outline, at the vertices ±a along the axis
    centre = (np.array(mask.shape) - 1) / 2
    ends = np.linalg.norm(m.points[[0, -1]] - centre, axis=1)
    assert np.abs(ends - a).max() < 1.0


def test_a_bent_capsule_midline_is_its_arc_plus_two_half_widths():
    radius, half_width, span = 100.0, 0.3, 1.2
    m = midline(pfsdm(bent_capsule_mask(radius, half_width=half_width, span=span)), bins=10)
    w = half_width * radius
    assert abs(m.length - (radius * span + 2 * w)) < 1.0
    assert abs(m.width_max - 2 * w) < 1.0
    # the straight part of the tube (away from the round caps) is 2w wide throughout
    assert np.abs(m.width_bins[3:7] - 2 * w).max() < 0.5


def test_a_linear_reporter_ramp_gives_a_linear_profile_its_direction_and_the_anterior_end():
    a, b, bins = 80.0, 30.0, 8
    mask, x, _ = ellipse(a, b)
    ramp = 100.0 + x  # rises along +x (the columns)
    res = pfsdm(mask)
    high = midline(res, ramp, bins=bins)
    assert high.anterior == "reporter"
    assert high.points[0, 1] > high.points[-1, 1]  # anterior: the high (right) end
    assert np.all(np.diff(high.reporter_bins) < 0)
    low = midline(res, ramp, bins=bins, anterior="reporter_low")
    assert np.all(np.diff(low.reporter_bins) > 0)
    # each bin's mean x is the chord-weighted mean of x over its piece of the axis
    xs = np.linspace(-a, a, 20001)
    chord = np.sqrt(np.clip(1 - (xs / a) ** 2, 0, None))
    piece = np.minimum(((xs + a) / (2 * a) * bins).astype(int), bins - 1)
    expected = 100.0 + np.bincount(piece, xs * chord) / np.bincount(piece, chord)
    assert np.abs(low.reporter_bins - expected).max() < 1.0
    # direction: the reporter's centre of mass lies towards +x, i.e. 0° in the image; towards
    # the anterior end under the default rule (180° from anterior→posterior), posterior else
    assert abs(high.polarity_angle_image) < 1.0
    assert abs(high.polarity_angle_midline - 180.0) < 1.0
    assert abs(low.polarity_angle_midline) < 1.0
    falling = midline(res, 100.0 - x, bins=bins)
    assert abs(abs(falling.polarity_angle_image) - 180.0) < 1.0


def test_turning_the_object_turns_the_angles_and_keeps_the_lengths():
    mask, x, _ = ellipse(70.0, 25.0, 20.0)
    ramp = 100.0 + x
    before = midline(pfsdm(mask), ramp)
    turned = midline(pfsdm(np.rot90(mask)), np.rot90(ramp))  # 90° counter-clockwise as shown
    assert abs(turned.length - before.length) < 0.5
    assert np.abs(turned.width_bins - before.width_bins).max() < 0.5
    diff = (turned.polarity_angle_image - before.polarity_angle_image) % 360
    assert abs(diff - 90.0) < 0.5
    assert abs(turned.polarity_angle_midline - before.polarity_angle_midline) < 1.0
    # a bin edge may move by a fraction of a pixel (the raster skeleton is not exactly
    # turned): < 1 on a ramp of 1 per pixel
    assert np.abs(turned.reporter_bins - before.reporter_bins).max() < 1.0


def test_the_first_and_last_rules_and_the_fallback_without_a_reporter():
    mask, _, _ = ellipse(60.0, 20.0)  # lies left-right
    res = pfsdm(mask)
    first, last = midline(res, anterior="first"), midline(res, anterior="last")
    assert first.points[0, 1] < first.points[-1, 1]  # the left end first
    assert last.points[0, 1] > last.points[-1, 1]
    fallback = midline(res)  # "reporter" without one
    assert fallback.anterior == "first"
    assert np.allclose(fallback.points, first.points)
    assert fallback.reporter_bins is None and np.isnan(fallback.polarity_angle_image)
    upright = midline(pfsdm(np.rot90(mask)), anterior="first")
    assert upright.points[0, 0] < upright.points[-1, 0]  # the top end first


def test_a_pixel_size_scales_lengths_and_widths_only():
    mask, _, _ = ellipse(60.0, 20.0)
    res = pfsdm(mask)
    px, um = midline(res), midline(res, pixel_size=0.5)
    assert um.length == pytest.approx(0.5 * px.length)
    assert um.width_bins == pytest.approx(0.5 * px.width_bins)
    assert np.allclose(um.points, px.points)


def test_a_round_object_still_has_an_axis_across_it():
    yy, xx = np.mgrid[:81, :81]
    disk = (yy - 40) ** 2 + (xx - 40) ** 2 <= 30**2
    m = midline(pfsdm(disk))
    assert abs(m.length - 60.0) < 1.5
    assert abs(m.width_max - 60.0) < 1.5
    # a small box whose skeleton is shorter than its half-width: the pixels' major axis
    box = np.pad(np.ones((6, 10), bool), 3)
    m = midline(pfsdm(box))
    assert abs(m.length - 10.0) < 0.5 and abs(m.width_max - 6.0) < 0.5


def test_the_columns_follow_the_names():
    mask, x, _ = ellipse(60.0, 20.0)
    m = midline(pfsdm(mask), 100.0 + x, bins=4)
    assert list(m.columns()) == midline_columns(4, with_intensity=True)
    assert list(midline(pfsdm(mask), bins=4).columns()) == midline_columns(4)


def test_measure_appends_the_midline_columns_after_the_classic_measures():
    import napari_pfsdm as pf
    from napari_pfsdm.analysis.classic import REPORTER_MEASURES, SHAPE_MEASURES_2D
    from napari_pfsdm.analysis.features import describe_object
    from napari_pfsdm.core.params import PFSDMParams

    mask, x, _ = ellipse(40.0, 15.0, 25.0)
    labels = np.zeros((2, *mask.shape), np.uint8)
    labels[0][mask] = 3
    labels[1][np.rot90(mask)] = 3
    reporter = np.stack([100.0 + x, np.rot90(100.0 + x)])
    table = pf.measure(labels, reporter, profile_bins=4, anterior="reporter_low")
    cols = list(table.columns)
    start = cols.index("perimeter")
    classic = [*SHAPE_MEASURES_2D, *REPORTER_MEASURES]
    assert cols[start:start + len(classic)] == classic
    new = midline_columns(4, with_intensity=True)
    assert cols[start + len(classic):start + len(classic) + len(new)] == new
    assert cols[start + len(classic) + len(new)] == "shape_r00_n00"
    assert table.attrs["pfsdm"]["profile_bins"] == 4
    assert table.attrs["pfsdm"]["anterior"] == "reporter_low"
    # the row holds what the object's own midline says
    obj = describe_object(labels, reporter, 0, 3,
                          params=PFSDMParams(profile_bins=4, anterior="reporter_low"))
    assert table.loc[0, new].to_numpy(float) == pytest.approx(
        np.array([obj.measures[c] for c in new], float))
    assert abs(table.loc[0, "midline_length"] - 80.0) < 1.5
    assert np.all(np.diff(table.loc[0, new[7:11]].to_numpy(float)) > 0)  # low end first
    turned = (table.loc[1, "polarity_angle_image"] - table.loc[0, "polarity_angle_image"]) % 360
    assert abs(turned - 90.0) < 1.0
    # the shape features do not depend on the midline's options
    plain = pf.measure(labels, profile_bins=10)
    assert "reporter_b00" not in plain.columns and "width_b09" in plain.columns
    shape = [c for c in cols if c.startswith("shape_")]
    assert np.array_equal(plain[shape].to_numpy(), table[shape].to_numpy())


def test_a_3d_table_has_no_midline_columns_and_refuses_their_option():
    import napari_pfsdm as pf
    from napari_pfsdm.data.volumes import blob_volume

    volume = blob_volume("tetrahedron", size=(20, 32, 32), radius=8).astype(np.uint8)
    table = pf.measure(volume, axes="zyx")
    assert not set(midline_columns(10)) & set(table.columns)
    with pytest.raises(ValueError, match="profile_bins was set, but the objects are 3-D"):
        pf.measure(volume, axes="zyx", profile_bins=10)


def test_the_picture_of_the_midline_is_what_the_table_measured():
    import napari_pfsdm as pf
    from napari_pfsdm.analysis.pictures import object_midline
    from napari_pfsdm.core.params import PFSDMParams
    from napari_pfsdm.data.gastruloids import make_timelapse_montage

    labels, reporter, _ = make_timelapse_montage(seed=0)
    params = PFSDMParams(profile_bins=5)
    table = pf.measure(labels[:2], reporter[:2], params=params)
    row = table.iloc[len(table) - 1]
    m = object_midline(labels[:2], reporter[:2], int(row.frame), int(row.label), params=params,
                       axes="tyx")
    got = m.columns()
    assert np.array([got[c] for c in got]) == pytest.approx(row[list(got)].to_numpy(float))
    # what the plugin draws: the path from outline to outline, and one section per bin
    assert m.points.shape == (5 * 10 + 1, 2) and m.cross_sections().shape == (5, 2, 2)
    sections = np.linalg.norm(np.diff(m.cross_sections(), axis=1)[:, 0], axis=1)
    assert sections == pytest.approx(m.width[5::10])


def test_no_bins_means_no_midline_measures_and_the_same_other_columns():
    import napari_pfsdm as pf

    labels = np.zeros((2, 64, 96), np.uint8)
    yy, xx = np.mgrid[:64, :96]
    labels[:, ((yy - 32) / 20) ** 2 + ((xx - 48) / 40) ** 2 <= 1] = 2
    full, bare = pf.measure(labels, profile_bins=10), pf.measure(labels)  # 0: the default
    gone = [c for c in full.columns if c not in bare.columns]
    assert gone[:3] == ["midline_length", "width_mean", "width_max"] and len(gone) == 13
    pd.testing.assert_frame_equal(full[list(bare.columns)], bare, check_like=True)
