"""The report to share (issue 55, point 5): one self-contained HTML file of a run.

Written by the library (napari_pfsdm.report.write_report) and by ``pfsdm report``, on the
bundled synthetic time-lapse; checked as text (no link out, every figure an inline PNG, user
text escaped, the sections there) and in a real headless browser (Debian's Chromium driven by
Playwright): every image loaded, no script error logged. That test skips where there is no
Chromium or no Playwright; ``PFSDM_DOCS_SCREENSHOTS=1`` also saves its screenshot as
docs/report.png.
"""

from __future__ import annotations

import base64
import io
import os
import re
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from napari_pfsdm import measure
from napari_pfsdm.cli import main
from napari_pfsdm.data.gastruloids import make_timelapse_montage
from napari_pfsdm.errors import InputError
from napari_pfsdm.io import write_table
from napari_pfsdm.report import write_report

#: A group name a person could type, that HTML must not read as markup.
ODD = "multi <b>&\"axes\""
SECTIONS = ("findings", "trajectories", "over-time", "pcs", "gallery", "nearest", "counts",
            "options")
#: What the findings say when predictions are given.
PREDICTED = "Predicting the groups from the features"
CHROMIUM = Path("/usr/bin/chromium")
DOCS = Path(__file__).resolve().parents[1] / "docs"


@pytest.fixture(scope="module")
def run():
    labels, reporter, groups = make_timelapse_montage(seed=0)
    groups = {k: ODD if v == "multi-axes" else v for k, v in groups.items()}
    return labels, measure(labels, reporter), groups


@pytest.fixture(scope="module")
def files(run, tmp_path_factory):
    """features.csv (+ sidecar), groups.csv, labels.tif and predictions.csv of the run."""
    import tifffile

    labels, table, groups = run
    d = tmp_path_factory.mktemp("report")
    write_table(table, d / "features.csv", table.attrs["pfsdm"], table_type="features")
    pd.DataFrame({"label": list(groups), "group": list(groups.values())}).to_csv(
        d / "groups.csv", index=False)
    tifffile.imwrite(d / "labels.tif", labels)
    tifffile.imwrite(d / "reporter.tif", labels.astype(np.float32))  # an image, not labels
    assert main(["predict", str(d / "features.csv"), "--groups", str(d / "groups.csv"),
                 "--splits", "3", "--repeats", "1", "-q",
                 "-o", str(d / "predictions.csv")]) == 0
    return d


@pytest.fixture(scope="module")
def library_report(run, tmp_path_factory):
    from napari_pfsdm.analysis.outcome import predict_outcome

    labels, table, groups = run
    pred = predict_outcome(table, groups, n_splits=3, n_repeats=1)
    out = tmp_path_factory.mktemp("lib") / "report.html"
    assert write_report(out, table, groups=groups, labels=labels, predictions=pred,
                        title="Gastruloids <i>&") == out
    return out


def _images(text: str) -> list[str]:
    return re.findall(r"<img\b[^>]*>", text)


def _check_self_contained(text: str) -> None:
    assert "http://" not in text and "https://" not in text
    assert "<script" not in text.lower() and "url(" not in text
    imgs = _images(text)
    assert imgs
    from PIL import Image

    for tag in imgs:
        src = re.search(r'src="([^"]*)"', tag)[1]
        assert src.startswith("data:image/png;base64,"), src[:60]
        data = base64.b64decode(src.split(",", 1)[1], validate=True)
        with Image.open(io.BytesIO(data)) as im:
            im.verify()  # a whole, valid PNG
            assert im.format == "PNG"
    # the only src/href values: inline images and the page's own anchors
    for attr in re.findall(r'(?:src|href)="([^"]*)"', text):
        assert attr.startswith(("data:image/png;base64,", "#")), attr


def test_the_library_writes_one_self_contained_page(library_report):
    text = library_report.read_text(encoding="utf-8")
    _check_self_contained(text)
    sections = re.findall(r'<section id="([^"]+)">', text)
    assert sections == list(SECTIONS)  # findings first; counts, options and methods last
    assert PREDICTED in text
    # user text is escaped: no markup from a group name or the title
    assert "<b>&" not in text and "<i>&" not in text
    assert "multi &lt;b&gt;&amp;&quot;axes&quot;" in text
    assert "<title>Gastruloids &lt;i&gt;&amp;</title>" in text
    # what the sections say
    assert "follows circularity" in text  # PC1, from the classic measures
    assert 'alt="balanced accuracy against the last frame used' in text
    findings = text.split('<section id="findings">')[1].split("</section>")[0]
    assert "the groups differ" in findings.lower() or "do not differ" in findings
    assert "Mann-Whitney U <span class=\"gloss\">(" in findings  # glossed where first said
    assert findings.count('class="gloss"') == len(set(re.findall(
        r'(\w[\w\' -]*) <span class="gloss">', findings)))  # each term glossed once
    assert "confusion matrix" in findings and "chance 0.50" in findings
    assert text.count('alt="real objects at') == 3  # -2σ … +2σ of PC1 … PC3, from the labels
    assert "need the labels" not in text
    n_gallery = 3 * 2 * 3  # PCs x ends x objects
    assert len(_images(text)) >= 1 + 1 + 3 * 2 + 1 + n_gallery
    assert library_report.stat().st_size < 2_000_000  # modest: PNGs at 100 dpi


def test_without_labels_the_report_says_the_outlines_need_them(run, tmp_path):
    labels, table, groups = run
    out = write_report(tmp_path / "r.html", table, groups=groups)
    text = out.read_text(encoding="utf-8")
    _check_self_contained(text)
    assert "need the labels" in text
    assert PREDICTED not in text  # none given: no prediction


def test_several_movies_tracks_and_left_out_rows(run):
    """A linked table of two movies (one named with markup), objects left out by min_area:
    the counts say why (one line per kind of reason), the outlines come from each movie."""
    import pandas as pd

    from napari_pfsdm.analysis.report import report_html
    from napari_pfsdm.analysis.tracking import link
    from napari_pfsdm.core.table_options import carry_options

    labels = run[0][:4]
    one = measure(labels, min_area=300)
    one.insert(0, "movie", "<m>&")
    two = carry_options(one, pd.concat([one, one.assign(movie="plain")], ignore_index=True))
    two = link(two, method="centroid")
    text = report_html(two, labels={"<m>&": labels, "plain": labels})
    _check_self_contained(text)
    assert "<m>&" not in text and "&lt;m&gt;&amp;: frame" in text  # gallery captions
    counts = text.split('<section id="counts">')[1].split("</section>")[0]
    n_small = int((one["error"] != "").sum())
    assert n_small > 1
    assert "<td>tracks</td><td>12</td>" in counts  # 6 per movie, not 6 ids
    assert counts.count("The object is too small to describe its shape</td>") == 1
    assert f'<td class="num">{2 * n_small}</td>' in counts
    assert text.count('alt="real objects at') == 3


def test_it_rewrites_its_own_report_and_never_a_foreign_file(run, tmp_path):
    labels, table, _ = run
    small = table[table["frame"] < 3]
    out = write_report(tmp_path / "r.html", small)
    write_report(out, small, title="again")  # its own: replaced without force
    assert "<title>again</title>" in out.read_text(encoding="utf-8")
    mine = tmp_path / "mine.html"
    mine.write_text("<!DOCTYPE html><p>my notes</p>", encoding="utf-8")
    with pytest.raises(InputError, match="not written by pfsdm"):
        write_report(mine, small)
    assert mine.read_text(encoding="utf-8") == "<!DOCTYPE html><p>my notes</p>"
    write_report(mine, small, force=True)
    assert "PF-SDM report" in mine.read_text(encoding="utf-8")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["mine.html", "r.html"]  # no temp
    with pytest.raises(InputError, match="is a folder"):
        write_report(tmp_path, small)


def test_pfsdm_report_writes_the_page_from_files(files, capsys):
    out = files / "cli.html"
    args = ["report", str(files / "features.csv"), "-o", str(out), "--groups",
            str(files / "groups.csv"), "--labels", str(files / "labels.tif"),
            "--predictions", str(files / "predictions.csv"), "--title", "Batch <3 & co"]
    assert main(args) == 0
    assert f"wrote {out}" in capsys.readouterr().out
    text = out.read_text(encoding="utf-8")
    _check_self_contained(text)
    assert re.findall(r'<section id="([^"]+)">', text) == list(SECTIONS)
    assert "Batch &lt;3 &amp; co" in text and "multi &lt;b&gt;&amp;" in text
    assert PREDICTED in text and "confusion matrix" in text  # from the predictions' sidecar
    assert 'alt="balanced accuracy against the last frame used' in text
    assert text.count('alt="real objects at') == 3
    assert main([*args, "-q"]) == 0  # its own report: replaced without --force


@pytest.mark.parametrize("case, message", [
    ("missing", "no such"),
    ("not_html", "ending in .html"),
    ("foreign", "not written by pfsdm"),
    ("predictions_without_p", "no p_<group> columns"),
    ("labels_twice", "same movie name"),
    ("reporter_as_labels", "not whole numbers"),
])
def test_pfsdm_report_refuses_in_plain_words(files, tmp_path, capsys, case, message):
    features = str(files / "features.csv")
    out = tmp_path / "r.html"
    args = ["report", features, "-o", str(out)]
    if case == "missing":
        args[1] = str(tmp_path / "nothing.csv")
    elif case == "not_html":
        args[3] = str(tmp_path / "r.png")
    elif case == "foreign":
        out.write_text("notes", encoding="utf-8")
    elif case == "predictions_without_p":
        args += ["--predictions", str(files / "groups.csv")]
    elif case == "reporter_as_labels":
        args += ["--labels", str(files / "reporter.tif")]
    elif case == "labels_twice":
        args += ["--labels", str(files / "labels.tif"), str(files / "labels.tif")]
    assert main(args) == 2
    err = capsys.readouterr().err
    assert err.startswith("pfsdm: error:") and message in err, err
    if case != "foreign":
        assert not out.exists()


def _browser_missing() -> str:
    if not CHROMIUM.exists():
        return f"no Chromium at {CHROMIUM} (apt-get install chromium)"
    try:
        import playwright.sync_api  # noqa: F401
    except ImportError:
        return "Playwright is not installed (pip install playwright; no browser download)"
    return ""


@pytest.mark.skipif(bool(_browser_missing()), reason=_browser_missing() or "ok")
def test_the_report_opens_in_a_real_browser(library_report, tmp_path):
    """Debian's Chromium, headless and offline, opens the file: every image decoded, no
    script error or failed request logged. Its screenshot (1280 wide, the whole page) is
    checked not to be blank and, with PFSDM_DOCS_SCREENSHOTS=1, saved as docs/report.png."""
    from playwright.sync_api import sync_playwright

    profile = tmp_path / "profile"
    shot = tmp_path / "report.png"
    with sync_playwright() as p:
        browser = p.chromium.launch_persistent_context(
            str(profile), executable_path=str(CHROMIUM), headless=True,
            viewport={"width": 1280, "height": 900},
            args=["--no-sandbox", "--disable-gpu", "--disable-background-networking",
                  "--disable-component-update", "--disable-sync", "--no-first-run"])
        try:
            page = browser.new_page()
            logged, failed = [], []
            page.on("console", lambda m: logged.append((m.type, m.text)))
            page.on("pageerror", lambda e: logged.append(("pageerror", str(e))))
            page.on("requestfailed", lambda r: failed.append(r.url[:80]))
            page.goto(library_report.resolve().as_uri(), wait_until="load")
            images = page.evaluate(
                "Array.from(document.images).map(i => [i.complete, i.naturalWidth])")
            sections = page.evaluate(
                "Array.from(document.querySelectorAll('section')).map(s => s.id)")
            page.screenshot(path=str(shot), full_page=True)
        finally:
            browser.close()
    assert len(images) >= 20
    assert all(done and width > 0 for done, width in images), images
    assert [kind for kind, _ in logged if kind in ("error", "pageerror")] == [], logged
    assert failed == []
    assert set(SECTIONS) <= set(sections)
    from PIL import Image

    with Image.open(shot) as im:
        assert im.width == 1280 and im.height > 2000
        grey = np.asarray(im.convert("L"), dtype=float)
        assert grey.std() > 10  # not a blank page
        if os.environ.get("PFSDM_DOCS_SCREENSHOTS") == "1":
            # full colour: a 256-colour palette loses either viridis or the faint loadings
            im.convert("RGB").save(DOCS / "report.png", optimize=True)


def test_the_captions_of_the_objects_along_a_pc_never_overlap():
    """Five objects of movies with long names, each captioned under its picture: no two
    texts of the figure (titles, captions) share a pixel once it is drawn."""
    from napari_pfsdm.analysis.report import modes_figure

    rng = np.random.default_rng(0)
    n = 40
    scores = pd.DataFrame({"movie": [f"plate_2024_{i:02d}_very_long_organoid_name"
                                     for i in range(n)],
                           "frame": rng.integers(0, 30, n), "label": rng.integers(1, 500, n),
                           "shape_PC1": rng.normal(size=n)})

    class NoMasks:
        ndim = 2

        def mask(self, row):
            yy, xx = np.mgrid[:20, :20]
            return (yy - 10) ** 2 + (xx - 10) ** 2 < 60

    from matplotlib.backends.backend_agg import FigureCanvasAgg

    fig = modes_figure(scores, 1, NoMasks(), several=True)
    renderer = FigureCanvasAgg(fig).get_renderer()
    fig.draw(renderer)
    boxes = []
    for ax in fig.axes:  # the texts drawn: each picture's title and caption
        for text in (ax.title, ax.xaxis.label, *ax.texts):
            if text.get_text() and text.get_visible() and (
                    text is not ax.xaxis.label or ax.axison):
                boxes.append(text.get_window_extent(renderer))
    assert len(boxes) == 2 * len(fig.axes) == 10
    for i, a in enumerate(boxes):
        for b in boxes[i + 1:]:
            assert not a.overlaps(b), (a, b)


def test_the_trajectories_colour_bar_is_labelled_with_the_time_and_its_unit(run, monkeypatch):
    # every text of every figure the page draws, as matplotlib lays it out
    from matplotlib.figure import Figure

    from napari_pfsdm.analysis.physical import add_times
    from napari_pfsdm.analysis.report import report_html

    labels, table, groups = run
    days = [2.0 + 3 * t for t in range(int(table["frame"].max()) + 1)]
    drawn: list[str] = []
    save = Figure.savefig

    def savefig(fig, *args, **kwargs):
        drawn.extend(t.get_text() for t in fig.findobj(lambda a: hasattr(a, "get_text")))
        return save(fig, *args, **kwargs)

    monkeypatch.setattr(Figure, "savefig", savefig)
    report_html(add_times(table, days, "day"), groups=groups)
    assert "time (day)" in drawn  # the colour bar of the trajectories, among others
    assert not [t for t in drawn if t.lstrip().startswith("[")]  # never the values' array


def test_pfsdm_report_takes_the_labels_folder_as_measure_does(files, tmp_path):
    import shutil

    folder = tmp_path / "movies"
    folder.mkdir()
    shutil.copy(files / "labels.tif", folder / "labels.tif")  # the folder pfsdm measured
    out = tmp_path / "r.html"
    assert main(["report", str(files / "features.csv"), "-o", str(out), "--labels",
                 str(folder), "-q"]) == 0
    assert "need the labels" not in out.read_text()  # the outlines are drawn
