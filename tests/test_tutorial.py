"""docs/tutorial.md runs: every ``pfsdm`` command of it and its Python block, in a folder laid
out as the tutorial's, on the synthetic study (examples/synthetic_study.py: four groups of
known growth rates, uneven days, two microscopes), with the tutorial's one substitution for it
(``--group-column group``)."""

from __future__ import annotations

import glob
import os
import re
import shlex
from pathlib import Path

import pandas as pd
import pytest

from napari_pfsdm.cli import main
from synthetic_study import write_study

TUTORIAL = Path(__file__).resolve().parents[1] / "docs" / "tutorial.md"


def _blocks(kind: str) -> list[str]:
    return re.findall(rf"```{kind}\n(.*?)```", TUTORIAL.read_text(), flags=re.S)


def _commands() -> list[list[str]]:
    out = []
    for block in _blocks("bash"):
        for line in block.splitlines():
            if line.startswith("pfsdm "):
                words = shlex.split(line.replace("--group-column clone", "--group-column group"))
                expanded = []
                for w in words[1:]:
                    expanded += sorted(glob.glob(w)) if "*" in w else [w]
                out.append(expanded)
    return out


@pytest.mark.slow
def test_the_tutorial_runs_on_the_synthetic_study(tmp_path, monkeypatch, capsys):
    write_study(tmp_path / "study", per_group=4)
    monkeypatch.chdir(tmp_path)
    commands = _commands()
    assert [c[0] for c in commands] == ["measure", "measure", "stats", "stats", "plot",
                                        "classify", "predict", "trajectories", "predict",
                                        "report"]
    for command in commands:
        assert main([*command, "-q"] if command[0] != "measure" else command) == 0, command
    said = capsys.readouterr()
    # what the tutorial says you should see, on the synthetic study's known answers
    assert "measuring: 100%" in said.err and "times given; pixel size from ImageJ" in said.out
    growth = pd.read_csv("growth_per_organoid.csv").groupby("group")["value"].median()
    assert growth["C"] > growth["B"] > growth["A"] and abs(growth["A"] - 900) < 150
    assert pd.read_csv("growth.csv")["p_value"].iloc[0] < 0.01
    scores = pd.read_csv("scores.csv").set_index("family")["balanced_accuracy"]
    assert scores["fused"] > scores["chance"] + 0.3
    other = pd.read_csv("labB_predicted.csv")
    truth = pd.read_csv("study/groups.csv").assign(movie=lambda g: g["movie"].str[:-4])
    right = other.merge(truth, on="movie")
    assert len(right) == 16 and (right["predicted"] == right["group"]).mean() > 0.7
    text = Path("report.html").read_text()
    assert "What differs between the groups" in text and "confusion matrix" in text
    # the Python block, as it is
    code = _blocks("python")[0].replace('"clone"', '"group"')
    exec(compile(code, str(TUTORIAL), "exec"), {})
    assert "the groups differ" in capsys.readouterr().out
    assert os.path.getsize("report.html") < 3_000_000
