"""The fault battery, round 3 (issue 66), rule 5: names are data.

Group, movie and column names with ``$`` (matplotlib's math text), a leading ``_`` (which a
legend leaves out), HTML markup or a spreadsheet formula go through every figure, report and
table as written. Every figure a command saves is drawn and inspected: no text of it is read
as math, and the names are among its texts as the user wrote them.
"""

from __future__ import annotations

import html

import matplotlib
import numpy as np
import pandas as pd
import pytest
import tifffile
from matplotlib.figure import Figure
from matplotlib.text import Text

import napari_pfsdm as pf
from napari_pfsdm.cli import main
from shapes_fixture import drifting_ellipses

matplotlib.use("Agg")

NAMES = ["cost $5 vs $_", r"$\frac$", "_hidden", "a\\$b", "<b>&amp;</b>", "=1+1"]
FAST = ["--n-fourier", "4", "--n-radii", "4", "--scheduler", "sync"]


@pytest.fixture()
def drawn(monkeypatch):
    """Every figure saved meanwhile: the texts it shows (after drawing), refusing math."""
    shown: list[list[str]] = []
    save = Figure.savefig

    def savefig(fig, *args, **kwargs):
        fig.canvas.draw()  # tick labels and legends exist once drawn
        texts = []
        for t in fig.findobj(Text):
            raw = t.get_text()
            if not raw:
                continue
            text, math = t._preprocess_math(raw)
            if math and r"\mathdefault" not in raw:  # matplotlib's own tick labels are math
                raise AssertionError(f"drawn as math text: {raw!r}")
            texts.append(text)
        shown.append(texts)
        return save(fig, *args, **kwargs)

    monkeypatch.setattr(Figure, "savefig", savefig)
    return shown


def ellipses(n_frames: int, n: int) -> np.ndarray:
    return drifting_ellipses(n_frames, n)


@pytest.fixture(scope="module")
def named(tmp_path_factory):
    """Two movies with names that are math text and markup, measured; groups named so."""
    folder = tmp_path_factory.mktemp("names")
    for movie in ("m$1$", "_m<2>"):
        tifffile.imwrite(folder / f"{movie}.tif", ellipses(3, 6), photometric="minisblack")
    assert main(["measure", str(folder / "m$1$.tif"), str(folder / "_m<2>.tif"), "-o",
                 str(folder / "f.csv"), "--link", "labels", "-q", *FAST]) == 0
    names = NAMES[:3] + NAMES[3:]
    rows = [f"{movie},{label},{names[(label + k) % len(names)]}"
            for k, movie in enumerate(("m$1$", "_m<2>")) for label in range(1, 7)]
    (folder / "g.csv").write_text("movie,label,group\n" + "\n".join(rows) + "\n")
    return folder


def _all(shown: list[list[str]]) -> str:
    return "\n".join(t for texts in shown for t in texts)


@pytest.mark.parametrize("command", ["trajectories", "compare", "plot", "report"])
def test_names_are_drawn_as_written_by_every_plotting_command(named, tmp_path, drawn,
                                                              capsys, command):
    f, g = str(named / "f.csv"), str(named / "g.csv")
    argv = {"trajectories": ["trajectories", f, "-o", str(tmp_path / "p.csv"), "--plot",
                             str(tmp_path / "p.png"), "--groups", g],
            "compare": ["compare", f, "-o", str(tmp_path / "d.csv"), "--mds",
                        str(tmp_path / "m.png"), "--groups", g],
            "plot": ["plot", f, "--column", "area", "-o", str(tmp_path / "a.png"),
                     "--groups", g],
            "report": ["report", f, "-o", str(tmp_path / "r.html"), "--groups", g,
                       "--labels", str(named / "m$1$.tif"), str(named / "_m<2>.tif")]}[command]
    assert main([*argv, "-q"]) == 0, capsys.readouterr().err
    texts = _all(drawn)
    assert drawn, "no figure drawn"
    for name in NAMES:  # in a legend or a panel's title
        assert name in texts, (name, texts[:2000])
    if command == "compare":  # objects named movie/t<frame>/l<label> beside their points
        assert "m$1$/t0/l1" in texts and "_m<2>/t0/l1" in texts
    if command == "report":
        page = (tmp_path / "r.html").read_text()
        for name in NAMES:
            assert html.escape(name, quote=True) in page
        assert "<b>&amp;</b>" not in page and "m$1$: frame" in texts


def test_a_column_name_with_math_is_drawn_as_written(named, tmp_path, drawn, capsys):
    t = pf.read_table(named / "f.csv")
    t["$x_1$ (µm)"] = t["area"] * 0.5
    pf.write_table(t, tmp_path / "t.csv")
    assert main(["plot", str(tmp_path / "t.csv"), "--column", "$x_1$ (µm)", "-o",
                 str(tmp_path / "x.png"), "-q"]) == 0, capsys.readouterr().err
    assert "$x_1$ (µm) over time" in _all(drawn)


def test_names_in_the_tables_are_data_too(named, tmp_path):
    """The scores table keeps every name as written, and a spreadsheet shows them as text."""
    assert main(["trajectories", str(named / "f.csv"), "-o", str(tmp_path / "p.csv"),
                 "--groups", str(named / "g.csv"), "-q"]) == 0
    back = pf.read_table(tmp_path / "p.csv")
    assert set(back["group"]) == set(NAMES)
    assert set(back["movie"]) == {"m$1$", "_m<2>"}
    raw = pd.read_csv(tmp_path / "p.csv", dtype=str)
    assert "'=1+1" in set(raw["group"])  # escaped for spreadsheets, read back as written


def test_the_python_figures_take_names_as_data(drawn, tmp_path):
    from napari_pfsdm.analysis.over_time import plot_over_time
    from napari_pfsdm.batch.reports import plot_mds

    t = pf.measure(ellipses(2, 4), n_fourier=4, n_radii=4)
    t["group"] = [NAMES[i % len(NAMES)] for i in range(len(t))]
    fig = Figure()
    plot_over_time(fig.subplots(), t, "area")
    fig.savefig(tmp_path / "o.png")
    plot_mds(np.random.default_rng(0).normal(size=(len(t), 2)), t, tmp_path / "m.png",
             title="map of $x$")
    texts = _all(drawn)
    assert "map of $x$" in texts
    for name in NAMES[:4]:
        assert f"{name} (mean ± sd)" in texts and name in texts
