"""Every ``pfsdm`` option changes what its help says it changes (e.g. ``compare
--boundary-weight`` is not ignored). Expected values come from the method's
formulas (D = d_SDF + λ d_B with d_SDF² = d_shape² + w_I d_intensity², docs/design.md §2.6),
not from the code under test."""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest
import tifffile

from napari_pfsdm.cli import main
from napari_pfsdm.io import read_table

FAST = ["--n-fourier", "6", "--n-radii", "8", "--scheduler", "sync", "-q"]


def three_objects(n_frames: int = 3) -> tuple[np.ndarray, np.ndarray]:
    yy, xx = np.mgrid[:64, :120]
    labels = np.zeros((n_frames, 64, 120), np.uint16)
    for t in range(n_frames):
        labels[t][((yy - 20) / (10 + 2 * t)) ** 2 + ((xx - 20) / 8) ** 2 < 1] = 1
        labels[t][(abs(yy - 40) < 6 + t) & (abs(xx - 60) < 15 - t)] = 2
        labels[t][((yy - 30) ** 2 + (xx - 100) ** 2) < (9 + t) ** 2] = 3
    intensity = (yy[None] * 0.5 + np.sin(xx[None] / 5.0) * 20 + 40.0
                 + 5.0 * np.arange(n_frames)[:, None, None]).astype(np.float32)
    return labels, intensity


@pytest.fixture(scope="module")
def features(tmp_path_factory):
    folder = tmp_path_factory.mktemp("opts")
    labels, intensity = three_objects()
    tifffile.imwrite(folder / "m.tif", labels, photometric="minisblack")
    tifffile.imwrite(folder / "m_i.tif", intensity, photometric="minisblack")
    out = folder / "features.csv"
    assert main(["measure", str(folder / "m.tif"), "--intensity", str(folder / "m_i.tif"),
                 "-o", str(out), "--link", "labels", *FAST]) == 0
    return out


def compare(features, tmp_path, *options: str) -> pd.DataFrame:
    out = tmp_path / f"d{len(list(tmp_path.iterdir()))}.csv"
    assert main(["compare", str(features), "-o", str(out), "-q", *options]) == 0
    return read_table(out, index_col=0)


def test_boundary_weight_scales_the_boundary_term(features, tmp_path):
    d0, d1, d2 = (compare(features, tmp_path, "--boundary-weight", w).to_numpy()
                  for w in ("0", "1", "2.5"))
    boundary = d1 - d0  # λ = 1: D = d_SDF + d_B
    assert boundary[~np.eye(9, dtype=bool)].min() > 0  # the term is there
    np.testing.assert_allclose(d2, d0 + 2.5 * boundary, rtol=1e-9, atol=1e-12)
    default = compare(features, tmp_path).to_numpy()
    np.testing.assert_allclose(default, d1, rtol=1e-12)  # λ = 1 is the default
    assert compare(features, tmp_path, "--boundary-weight", "2.5").attrs["pfsdm"][
        "boundary_weight"] == 2.5  # and the sidecar says which


def test_intensity_weight_adds_the_intensity_term_in_quadrature(features, tmp_path):
    d0, d1, d3 = (compare(features, tmp_path, "--boundary-weight", "0",
                          "--intensity-weight", w).to_numpy() for w in ("0", "1", "3"))
    intensity_sq = d1**2 - d0**2
    assert intensity_sq[~np.eye(9, dtype=bool)].min() > 0
    np.testing.assert_allclose(d3**2, d0**2 + 3 * intensity_sq, rtol=1e-9, atol=1e-12)


def test_frames_keeps_the_rows_of_those_frames(features, tmp_path):
    d = compare(features, tmp_path, "--frames", "1-2")
    assert d.index.tolist() == [f"m/t{t}/l{lab}" for t in (1, 2) for lab in (1, 2, 3)]
    full = compare(features, tmp_path)
    np.testing.assert_allclose(d.to_numpy(), full.iloc[3:, 3:].to_numpy(), rtol=1e-12)


def test_rerank_and_its_k_are_the_re_ranking_of_the_plain_matrix(features, tmp_path):
    from napari_pfsdm.analysis.rerank import rerank

    plain = compare(features, tmp_path).to_numpy()
    from napari_pfsdm.analysis.rerank import RERANK_METHODS

    for method in RERANK_METHODS:
        got = compare(features, tmp_path, "--rerank", method).to_numpy()
        np.testing.assert_allclose(got, rerank(plain, method, k=8), rtol=1e-12, atol=1e-14)
    k3 = compare(features, tmp_path, "--rerank", "diffusion", "--rerank-k", "3").to_numpy()
    np.testing.assert_allclose(k3, rerank(plain, "diffusion", k=3), rtol=1e-12, atol=1e-14)
    assert not np.allclose(k3, rerank(plain, "diffusion", k=8))


def test_max_objects_refuses_a_larger_matrix(features, tmp_path, capsys):
    assert main(["compare", str(features), "-o", str(tmp_path / "d.csv"),
                 "--max-objects", "8"]) == 2
    assert "9 objects would give a 9x9 matrix" in capsys.readouterr().err
    assert main(["compare", str(features), "-o", str(tmp_path / "d.csv"),
                 "--max-objects", "9", "-q"]) == 0


def test_mds_writes_the_map(features, tmp_path):
    png = tmp_path / "mds.png"
    compare(features, tmp_path, "--mds", str(png))
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_trajectories_channel_and_components(features, tmp_path):
    out = tmp_path / "p.csv"
    assert main(["trajectories", str(features), "-o", str(out), "--components", "2",
                 "--channel", "intensity", "-q"]) == 0
    scores = read_table(out)
    assert [c for c in scores.columns if "PC" in c] == ["intensity_PC1", "intensity_PC2"]
    assert main(["trajectories", str(features), "-o", str(out), "--components", "4",
                 "-q", "--force"]) == 0
    cols = [c for c in read_table(out).columns if c.startswith("shape_PC")]
    assert cols == [f"shape_PC{i}" for i in range(1, 5)]


@pytest.mark.parametrize("option, value, key", [
    ("--n-fourier", "5", "n_fourier"), ("--n-radii", "6", "n_radii"),
    ("--n-angles", "48", "n_angles"), ("--sdf", "viscous", "sdf"),
    ("--viscosity", "0.1", "viscosity"),  # with --sdf viscous (below)
    ("--mapping", "radial", "mapping"), ("--mapping", "radial", "mapping"),
    ("--normalization", "ring", "normalization"), ("--radii", "boundary", "radii"),
    ("--ring-weighting", "none", "ring_weighting"), ("--mode-exponent", "0.5", "mode_exponent"),
])
def test_each_method_option_reaches_the_table(tmp_path, option, value, key):
    labels, _ = three_objects(1)
    tifffile.imwrite(tmp_path / "m.tif", labels[0])
    out = tmp_path / "f.csv"
    base = ["--n-fourier", "6", "--n-radii", "8", "--scheduler", "sync", "-q"]
    base = [b for i, b in enumerate(base) if option not in base[max(0, i - 1):i + 1]]
    if key == "viscosity":
        base = [*base, "--sdf", "viscous"]
    assert main(["measure", str(tmp_path / "m.tif"), "-o", str(out), option, value,
                 *base]) == 0
    options = json.loads((tmp_path / "f.csv.json").read_text())["options"]
    recorded = options[key]
    n = np.arange(7)
    r = (np.arange(8) + 0.5) / 8
    if key == "radii":  # the rings are recorded as numbers: 1 − ((i + ½)/8)², sorted
        np.testing.assert_allclose(recorded, np.sort(1 - r**2), rtol=1e-15)
    else:
        assert recorded == type(recorded)(value)
    default = tmp_path / "g.csv"
    assert main(["measure", str(tmp_path / "m.tif"), "-o", str(default), *base]) == 0
    if key == "ring_weighting":  # the weights of the distance change, not the magnitudes
        np.testing.assert_allclose(options["weights"], [1 / 8] * 8, rtol=1e-15)
        return
    if key == "mode_exponent":
        np.testing.assert_allclose(options["mode_weights"], (1.0 + n) ** 0.5, rtol=1e-15)
        return
    a, b = read_table(out), read_table(default)
    cols = [c for c in b.columns if c.startswith("shape_")]
    if key in ("n_fourier", "n_radii"):
        assert [c for c in a.columns if c.startswith("shape_")] != cols
        return
    assert not np.allclose(a[cols].to_numpy(), b[cols].to_numpy())


def test_components_and_min_area_decide_which_objects_are_described(tmp_path):
    labels, _ = three_objects(1)
    frame = labels[0].copy()
    frame[2:6, 2:6] = 1  # object 1 in two pieces (16 px apart from its ellipse)
    small = np.zeros_like(frame)
    small[50:55, 110:115] = 4  # 25 pixels
    frame = np.where(small > 0, small, frame)
    tifffile.imwrite(tmp_path / "m.tif", frame)
    base = ["--n-fourier", "6", "--n-radii", "8", "--scheduler", "sync", "-q"]

    def errors(*options: str) -> dict[int, str]:
        out = tmp_path / "f.csv"
        assert main(["measure", str(tmp_path / "m.tif"), "-o", str(out), "--force",
                     *options, *base]) == 0
        table = read_table(out)
        return dict(zip(table["label"].tolist(), table["error"].tolist(), strict=True))

    default = errors()
    assert all(e == "" for e in default.values()) and set(default) == {1, 2, 3, 4}
    raised = errors("--components", "raise")
    assert raised[1] != "" and raised[2] == raised[3] == raised[4] == ""
    big = errors("--min-area", "30")  # 25 px < 30: object 4 is too small
    assert big[4] != "" and big[1] == big[2] == big[3] == ""
