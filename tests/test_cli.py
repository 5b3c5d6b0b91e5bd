"""The ``pfsdm`` command line: round trips on TIFF and Zarr, errors as one line, demo."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import tifffile

import napari_pfsdm
from napari_pfsdm.cli import main
from napari_pfsdm.io import read_table, write_table

zarr = pytest.importorskip("zarr")  # the [batch] extra

OPTS = ["--n-fourier", "6", "--n-radii", "8", "--scheduler", "threads", "-q"]
KW = {"n_fourier": 6, "n_radii": 8}


def make_movie(n_frames: int = 3, shape=(64, 80)):
    yy, xx = np.mgrid[: shape[0], : shape[1]]
    labels = np.zeros((n_frames, *shape), np.uint16)
    for t in range(n_frames):
        labels[t][((yy - 20) / (10 + t)) ** 2 + ((xx - 20) / 8) ** 2 < 1] = 1
        labels[t][(abs(yy - 45) < 6 + t) & (abs(xx - 55) < 15 - t)] = 2
    intensity = (yy[None] * 0.5 + xx[None] + 10.0 * np.arange(n_frames)[:, None, None])
    return labels, intensity.astype(np.float32)


def write_zarr(path: Path, data: np.ndarray) -> Path:
    z = zarr.create_array(str(path), shape=data.shape, dtype=data.dtype,
                          chunks=(1, *data.shape[1:]))
    z[:] = data
    return path


def features_close(got: pd.DataFrame, ref: pd.DataFrame) -> None:
    text = ("error", "warnings")
    cols = [c for c in ref.columns if c not in text]
    np.testing.assert_allclose(got[cols].to_numpy(float), ref[cols].to_numpy(float),
                               rtol=1e-12, atol=1e-12)
    for c in text:
        assert got[c].tolist() == ref[c].tolist()


def one_error_line(capsys) -> str:
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1, err
    assert err[0].startswith("pfsdm: error: ")
    return err[0]


def test_measure_tiff_round_trip(tmp_path):
    labels, intensity = make_movie()
    tifffile.imwrite(tmp_path / "emb_labels.tif", labels, photometric="minisblack")
    tifffile.imwrite(tmp_path / "emb_reporter.tif", intensity, photometric="minisblack")
    out = tmp_path / "features.csv"
    rc = main(["measure", str(tmp_path / "emb_labels.tif"),
               "--intensity", str(tmp_path / "emb_reporter.tif"), "-o", str(out), *OPTS])
    assert rc == 0
    got = read_table(out)
    ref = napari_pfsdm.measure(labels, intensity, **KW)
    assert got["movie"].unique().tolist() == ["emb_labels"]
    assert len(got) == len(ref) == 6
    assert any(c.startswith("intensity_r") for c in got.columns)
    features_close(got.drop(columns="movie"), ref)
    assert got.attrs["pfsdm"]["n_fourier"] == 6 and len(got.attrs["pfsdm"]["radii"]) == 8


def test_measure_zarr_folder_then_trajectories_and_compare(tmp_path, capsys):
    labels, _ = make_movie()
    movies = tmp_path / "movies"
    movies.mkdir()
    write_zarr(movies / "a.zarr", labels)
    write_zarr(movies / "b.zarr", labels[:, ::-1, :])  # mirror image: same shapes
    out = tmp_path / "features.csv"
    assert main(["measure", str(movies), "-o", str(out), *OPTS]) == 0
    table = read_table(out)
    assert table["movie"].tolist() == ["a"] * 6 + ["b"] * 6
    ref = napari_pfsdm.measure(labels, **KW)
    features_close(table[table.movie == "a"].drop(columns="movie").reset_index(drop=True), ref)

    groups = tmp_path / "groups.csv"
    groups.write_text("label,group\n1,round\n2,box\n")
    pca, png = tmp_path / "pca.csv", tmp_path / "pca.png"
    assert main(["trajectories", str(out), "-o", str(pca), "--plot", str(png),
                 "--groups", str(groups), "-q"]) == 0
    scores = read_table(pca)
    assert len(scores) == 12 and {"shape_PC1", "shape_PC2", "group"} <= set(scores.columns)
    assert png.stat().st_size > 10_000
    assert scores.loc[scores.label == 1, "group"].eq("round").all()

    dist, mds = tmp_path / "d.csv", tmp_path / "mds.png"
    assert main(["compare", str(out), "--frames", "0", "-o", str(dist),
                 "--mds", str(mds), "-q"]) == 0
    d = read_table(dist, index_col=0)
    assert d.shape == (4, 4) and d.index.tolist()[0] == "a/t0/l1"
    m = d.to_numpy()
    np.testing.assert_allclose(m, m.T)
    assert np.all(np.diag(m) == 0)
    # a mirrored object is (up to rasterisation) the same shape; the other object is not
    assert m[0, 2] < 0.2 * m[0, 1]
    assert mds.stat().st_size > 5_000


def test_classify_prints_scores(tmp_path, capsys):
    rng = np.random.default_rng(0)
    rows = []
    for obj in range(16):
        cls = obj % 2
        for t in range(3):
            feats = rng.normal(size=6) + 3.0 * cls * (t + 1)
            row = {"movie": f"m{obj:02d}", "frame": t, "label": 1, "error": ""}
            row.update({f"shape_r00_n{n:02d}": v for n, v in enumerate(feats[:3])})
            row.update({f"intensity_r00_n{n:02d}": v for n, v in enumerate(feats[3:])})
            rows.append(row)
    feats = tmp_path / "f.csv"
    pd.DataFrame(rows).to_csv(feats, index=False)
    groups = tmp_path / "g.csv"
    groups.write_text("movie,group\n")
    # a table without its options (no f.csv.json) is refused, not guessed
    assert main(["classify", str(feats), "--groups", str(groups), "--frames", "0-1"]) == 2
    assert "does not say how it was measured" in capsys.readouterr().err
    write_table(pd.DataFrame(rows), feats, {"n_fourier": 2, "weights": [1.0]})
    groups.write_text("movie,group\n" + "".join(
        f"m{o:02d},{'multi' if o % 2 else 'single'}\n" for o in range(16)))
    out = tmp_path / "scores.csv"
    assert main(["classify", str(feats), "--groups", str(groups), "--frames", "0-1",
                 "-o", str(out)]) == 0
    printed = capsys.readouterr().out
    assert "16 objects with a group (8 multi, 8 single)" in printed
    assert "fused (weights chosen inside each training split)" in printed
    scores = read_table(out).set_index("family")
    assert scores.loc["shape", "balanced_accuracy"] > 0.9  # separable by construction


@pytest.mark.parametrize("case", ["missing", "shapes", "float", "no_folder", "is_folder"])
def test_bad_inputs_give_one_line_and_status_2(tmp_path, capsys, case):
    labels, intensity = make_movie(2)
    lab = tmp_path / "labels.tif"
    tifffile.imwrite(lab, labels, photometric="minisblack")
    out = tmp_path / "features.csv"
    args = ["measure", str(lab), "-o", str(out), "-q", "--scheduler", "sync"]
    expect = {"missing": "no such file", "shapes": "different shapes",
              "float": "not a label image", "no_folder": "does not exist",
              "is_folder": "is a folder"}[case]
    if case == "missing":
        args[1] = str(tmp_path / "nope.tif")
    elif case == "shapes":
        tifffile.imwrite(tmp_path / "img.tif", intensity[:, :32], photometric="minisblack")
        args += ["--intensity", str(tmp_path / "img.tif")]
    elif case == "float":
        tifffile.imwrite(lab, intensity, photometric="minisblack")
    elif case == "no_folder":
        out = tmp_path / "absent" / "features.csv"
        args[3] = str(out)
    elif case == "is_folder":
        out = tmp_path
        args[3] = str(out)
    assert main(args) == 2
    assert expect in one_error_line(capsys)
    assert not (tmp_path / "features.csv").exists()
    assert not [p for p in os.listdir(tmp_path) if p.endswith(".tmp")]


def test_bad_feature_table(tmp_path, capsys):
    bad = tmp_path / "x.csv"
    bad.write_text("a,b\n1,2\n")
    assert main(["trajectories", str(bad), "-o", str(tmp_path / "p.csv")]) == 2
    assert "not a PF-SDM feature table" in one_error_line(capsys)
    assert not (tmp_path / "p.csv").exists()


def test_entry_point_and_module_in_a_subprocess(tmp_path):
    exe = Path(sys.executable).with_name("pfsdm")
    assert exe.exists(), "the console script is not installed (pip install -e .)"
    help_text = subprocess.run([str(exe), "measure", "--help"], capture_output=True, text=True,
                               check=True).stdout
    assert "--intensity" in help_text and "--scheduler" in help_text
    labels, intensity = make_movie(2)
    write_zarr(tmp_path / "m.zarr", labels)
    out = tmp_path / "f.csv"
    ok = subprocess.run([str(exe), "measure", str(tmp_path / "m.zarr"), "-o", str(out),
                         "--scheduler", "processes", "--workers", "2", *KW_ARGS],
                        capture_output=True, text=True)
    assert ok.returncode == 0, ok.stderr
    features_close(read_table(out).drop(columns="movie"),
                   napari_pfsdm.measure(labels, **KW))
    bad = subprocess.run([sys.executable, "-m", "napari_pfsdm", "measure",
                          str(tmp_path / "nope.zarr"), "-o", str(tmp_path / "g.csv")],
                         capture_output=True, text=True)
    assert bad.returncode == 2
    assert bad.stderr.strip().splitlines() == [
        f"pfsdm: error: {tmp_path / 'nope.zarr'}: no such file or folder"]
    assert "Traceback" not in bad.stderr and not (tmp_path / "g.csv").exists()


KW_ARGS = ["--n-fourier", "6", "--n-radii", "8"]


def test_demo_quick(tmp_path):
    out = tmp_path / "results"
    assert main(["demo", "-o", str(out), "--quick-only", "--scheduler", "threads", "-q"]) == 0
    for name in ("features.csv", "pca.csv", "pca.png", "distances.csv", "mds.png",
                 "groups.csv", "montage_labels.tif"):
        assert (out / name).exists(), name
    table = read_table(out / "features.csv")
    assert table["frame"].nunique() > 1 and table["label"].nunique() > 1
    assert any(c.startswith("intensity_r") for c in table.columns)
