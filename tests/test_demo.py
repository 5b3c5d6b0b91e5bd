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
