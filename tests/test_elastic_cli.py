"""``pfsdm compare --elastic``: the elastic outline term where users compare, from the shell."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
import tifffile

import napari_pfsdm as pf
from napari_pfsdm.cli import main
from napari_pfsdm.io import read_table


def _lobes(n_frames: int = 3) -> np.ndarray:
    """A movie of four kinds of outline (a square, a bar, an ellipse, a lobed shape) that
    turn and grow a little from frame to frame."""
    yy, xx = np.mgrid[:90, :330]
    out = np.zeros((n_frames, 90, 330), np.uint16)
    for t in range(n_frames):
        lab = out[t]
        lab[10:60 + t, 10:60] = 1
        lab[20:45, 75:140 + 2 * t] = 2
        lab[((yy - 45) / (30 - t)) ** 2 + ((xx - 180) / 20) ** 2 < 1] = 3
        r = np.hypot(yy - 45, xx - 260)
        a = np.arctan2(yy - 45, xx - 260) - 0.3 * t
        lab[(r < 30 + 8 * np.cos(3 * a) + 4 * np.sin(2 * a)) & (np.abs(xx - 260) < 55)] = 4
    return out


@pytest.fixture(scope="module")
def measured(tmp_path_factory):
    """features.csv measured with the signature's columns, and one without."""
    folder = tmp_path_factory.mktemp("elastic_cli")
    tifffile.imwrite(folder / "lobes.tif", _lobes(), photometric="minisblack")
    with_sig, without = folder / "features.csv", folder / "plain.csv"
    assert main(["measure", str(folder / "lobes.tif"), "-o", str(with_sig),
                 "--elastic-signature", "table", "-q"]) == 0
    assert main(["measure", str(folder / "lobes.tif"), "-o", str(without), "-q"]) == 0
    return with_sig, without


def test_compare_elastic_is_the_default_distance_plus_the_recommended_weight_times_d_e(
        measured, tmp_path):
    from napari_pfsdm.analysis.tables import signatures_from_table
    from napari_pfsdm.core.elastic import elastic_distance_matrix

    features, _ = measured
    table = read_table(features)
    want_default = pf.distance_matrix(table.drop(columns="movie"))
    d_e = elastic_distance_matrix(signatures_from_table(table))
    for flag, mu in ((["--elastic"], pf.RECOMMENDED_ELASTIC_WEIGHT), (["--elastic", "1.5"], 1.5)):
        out = tmp_path / f"d{mu}.csv"
        assert main(["compare", str(features), "-o", str(out), "-q", *flag]) == 0
        got = read_table(out, index_col=0)
        assert np.allclose(got.to_numpy(float), want_default + mu * d_e, atol=1e-9)
        assert got.attrs["pfsdm"]["elastic_weight"] == mu
    assert pf.RECOMMENDED_ELASTIC_WEIGHT == 0.375
    out = tmp_path / "plain.csv"
    assert main(["compare", str(features), "-o", str(out), "-q"]) == 0
    got = read_table(out, index_col=0)
    assert np.allclose(got.to_numpy(float), want_default, atol=1e-9)
    assert got.attrs["pfsdm"]["elastic_weight"] == 0.0


def test_compare_elastic_without_signatures_says_how_to_measure_them(measured, tmp_path,
                                                                      capsys):
    _, plain = measured
    rc = main(["compare", str(plain), "--elastic", "-o", str(tmp_path / "d.csv")])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2 and len(err) == 1
    assert "--elastic-signature table" in err[0] and str(plain) in err[0]
    assert not (tmp_path / "d.csv").exists()
    with pytest.raises(SystemExit) as stop:  # argparse's own refusal
        main(["compare", str(plain), "--elastic", "-1", "-o", str(tmp_path / "d.csv")])
    assert stop.value.code == 2 and "elastic_weight must be" in capsys.readouterr().err


def test_compare_elastic_neighbours_say_they_are_approximate(tmp_path, capsys):
    # 240 moving blobs: more than every object as a candidate, so the search is approximate
    from napari_pfsdm.data.moving_blobs import make_moving_blobs

    movie = make_moving_blobs(n_objects=60, n_frames=4, size=400, radius=(10.0, 16.0), seed=4)
    tifffile.imwrite(tmp_path / "blobs.tif", movie.labels.astype(np.uint16),
                     photometric="minisblack")
    features = tmp_path / "features.csv"
    assert main(["measure", str(tmp_path / "blobs.tif"), "-o", str(features),
                 "--elastic-signature", "table", "-q"]) == 0
    out = tmp_path / "edges.csv"
    capsys.readouterr()
    assert main(["compare", str(features), "--neighbours", "5", "--elastic",
                 "-o", str(out)]) == 0
    err = capsys.readouterr().err
    assert "approximate" in err
    edges = read_table(out)
    extra = edges.attrs["pfsdm"]
    assert extra["elastic_weight"] == pf.RECOMMENDED_ELASTIC_WEIGHT
    table = pf.drop_failed(read_table(features))
    found = pf.nearest_neighbours(table, 5, elastic_weight=pf.RECOMMENDED_ELASTIC_WEIGHT)
    assert not found.exact
    got = edges.sort_values(["row", "rank"])["neighbour"].to_numpy().reshape(-1, 5)
    rows = table.index.to_numpy()  # the features file's rows (none left out here)
    assert np.array_equal(got, rows[found.indices])


def test_compare_says_when_numba_compiles_the_elastic_kernel(measured, tmp_path, capsys,
                                                             monkeypatch):
    # a compile of the distance's kernel starting while compare runs (what a first use after
    # an install does): said on stderr once, nothing with -q
    from numba.core import event

    from napari_pfsdm.core import compiled, elastic_kernel
    from napari_pfsdm.core.elastic import SignatureSet

    real = SignatureSet.between

    def between(self, *args, **kwargs):
        with event.trigger_event("numba:compile", data={"dispatcher": elastic_kernel.pairs,
                                                        "args": (), "return_type": None}):
            pass
        return real(self, *args, **kwargs)

    monkeypatch.setattr(SignatureSet, "between", between)
    features, _ = measured
    for quiet, said in ((["-q"], 0), ([], 1)):
        monkeypatch.setattr(compiled, "_SAID", set())
        capsys.readouterr()
        assert main(["compare", str(features), "--elastic", "-o",
                     str(tmp_path / f"d{said}.csv"), *quiet]) == 0
        err = capsys.readouterr().err
        assert err.count("compiling the elastic kernel, once") == said
    assert isinstance(pd.read_csv(tmp_path / "d1.csv"), pd.DataFrame)


def test_the_report_s_nearest_shapes_are_under_the_elastic_distance(measured, tmp_path):
    # without labels the section lists each object and its nearest shapes with their
    # distances: each must be the full matrix's entry (with the term when --elastic) and the
    # nearest of its row
    import re

    features, _ = measured
    table = pf.drop_failed(read_table(features))
    keys = list(zip(table["frame"], table["label"], strict=True))
    for flag, mu in (([], 0.0), (["--elastic"], pf.RECOMMENDED_ELASTIC_WEIGHT)):
        out = tmp_path / f"report{mu}.html"
        assert main(["report", str(features), "-o", str(out), "-q", *flag]) == 0
        page = out.read_text()
        section = page[page.index('<section id="nearest">'):]
        section = section[:section.index("</section>")]
        d = pf.distance_matrix(table, elastic_weight=mu)
        np.fill_diagonal(d, np.inf)
        listed = 0
        for block in section.split("<table>")[1:]:
            rows = re.findall(r"<tr><td>frame (\d+), label (\d+)</td><td>([^<]*)</td></tr>",
                              block)
            q = keys.index((int(rows[0][0]), int(rows[0][1])))
            got = [(keys.index((int(f), int(lab))), float(v)) for f, lab, v in rows[1:]]
            want = np.sort(d[q])[:len(got)]
            assert np.allclose([v for _, v in got], want, rtol=1e-3)
            assert np.allclose([d[q, j] for j, _ in got], want, rtol=1e-3)
            listed += len(got)
        assert listed >= 8
        assert ("elastic outline term" in section) == bool(mu)
