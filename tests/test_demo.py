"""`pfsdm demo`: what its output says while it runs, and what its files are."""

from __future__ import annotations

import re

from napari_pfsdm.cli import main


def test_the_demo_counts_objects_as_they_are_measured(tmp_path, capsys):
    assert main(["demo", "--quick-only", "-o", str(tmp_path), "--scheduler", "threads"]) == 0
    err = capsys.readouterr().err
    # one bar, in objects (12 frames x 6 objects), that starts at 0 and ends at 72
    counts = [int(n) for n in re.findall(r"measuring:\s+\d+%\|.*?\| (\d+)/72 ", err)]
    assert counts and counts[0] == 0 and counts[-1] == 72, err[-2000:]
    assert "frame/s" not in err
    # the tables have their options beside them; groups.csv is the demo's input
    tables = sorted(p.name for p in tmp_path.glob("*.csv") if p.name != "groups.csv")
    assert tables == ["distances.csv", "features.csv", "pca.csv"]
    assert all((tmp_path / (t + ".json")).is_file() for t in tables)


def test_the_demo_finds_the_reports_in_the_checkout():
    """From a checkout (an editable install, as scripts/demo.sh makes) the demo imports the
    paper's reproductions of examples/ and runs their ``run``."""
    from napari_pfsdm.cli.demo import EXAMPLES, examples_folder, load_example

    assert examples_folder() is not None and (examples_folder() / "README.md").is_file()
    for _title, name in EXAMPLES:
        assert callable(load_example(name).run)


def test_without_a_checkout_the_demo_says_it_skips_the_reports(tmp_path, capsys, monkeypatch):
    from napari_pfsdm.cli import demo

    monkeypatch.setattr(demo, "examples_folder", lambda: None)
    assert demo._run_examples(tmp_path) == []  # skipped, not failed
    out = capsys.readouterr().out
    assert out.count("skipped: examples/") == len(demo.EXAMPLES)
    assert "bash scripts/demo.sh" in out
    assert not any(tmp_path.iterdir())
