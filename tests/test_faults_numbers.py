"""The fault battery, round 3 (issue 66), rule 4: ranges and numbers within what the data and
the machine hold.

Frames outside the table are refused naming them, at every command that takes ``--frames``
and in Python; ranges are read as ranges (``0-1000000000`` is refused in words, not listed);
ids of any size a file holds (uint64 up to 2**64 - 1) come through every command exactly;
seeds, workers and every number a command takes are bounded where they are declared (the
option record for the method's options), and a command added with an unbounded number fails
:func:`test_every_number_a_command_takes_is_bounded`.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import textwrap

import numpy as np
import pandas as pd
import pytest
import tifffile

import napari_pfsdm as pf
from napari_pfsdm.cli import build_parser, main
from napari_pfsdm.errors import InputError
from shapes_fixture import drifting_ellipses

FAST = ["--n-fourier", "4", "--n-radii", "4", "--scheduler", "sync"]


def ellipses(n_frames: int = 4, n: int = 8, dtype=np.uint16, ids=None) -> np.ndarray:
    """``n`` ellipses of two kinds drifting right; ``ids`` their labels (default 1 … n)."""
    return drifting_ellipses(n_frames, n, dtype, ids)


@pytest.fixture(scope="module")
def table(tmp_path_factory):
    folder = tmp_path_factory.mktemp("numbers")
    tifffile.imwrite(folder / "m.tif", ellipses(), photometric="minisblack")
    assert main(["measure", str(folder / "m.tif"), "-o", str(folder / "f.csv"), "--link",
                 "labels", "-q", *FAST]) == 0
    (folder / "g.csv").write_text("label,group\n" + "".join(
        f"{i},{'round' if i % 2 == 0 else 'long'}\n" for i in range(1, 9)))
    return folder


def error_line(capsys) -> str:
    err = capsys.readouterr().err
    assert "Traceback" not in err and "internal error" not in err, err
    lines = [ln for ln in err.splitlines() if "error:" in ln]
    assert len(lines) == 1, err
    return lines[0]


# --------------------------------------------------------------------------------------------
# frames
# --------------------------------------------------------------------------------------------

FRAMES = {  # --frames on a table of frames 0-3: the frames the message must name
    "0,10": "frame 10 is not in the table",
    "2-50": "frames 4-50 are not in the table",
    "0-3,7,9-12": "frames 7, 9-12 are not in the table",
    "5": "frame 5 is not in the table",
    "0-100000": "frames 4-100000 are not in the table",  # 10⁹: in a process of its own, below
}


def _frames_argv(command: str, folder, frames: str) -> list[str]:
    f, g = str(folder / "f.csv"), str(folder / "g.csv")
    return {"compare": ["compare", f, "--frames", frames, "-o", str(folder / "d.csv"), "-q"],
            "classify": ["classify", f, "--groups", g, "--frames", frames, "-q"],
            "predict": ["predict", f, "--groups", g, "--frames", frames, "-o",
                        str(folder / "p.csv"), "-q"]}[command]


@pytest.mark.parametrize("command", ["compare", "classify", "predict"])
@pytest.mark.parametrize("frames", sorted(FRAMES))
def test_frames_outside_the_table_are_refused_naming_them(table, capsys, command, frames):
    assert main(_frames_argv(command, table, frames)) == 2
    line = error_line(capsys)
    assert f"--frames {frames}: {FRAMES[frames]} (it has frames 0-3)" in line, line


def test_a_range_of_a_billion_frames_is_never_listed(table):
    """Under a memory limit of 1.5 GiB (a list of 10⁹ frames needs ~36 GB): refused in words."""
    code = textwrap.dedent(f"""
        import resource, sys
        resource.setrlimit(resource.RLIMIT_AS, (1536 * 2**20, 1536 * 2**20))
        from napari_pfsdm.cli import main
        sys.exit(main({_frames_argv("compare", table, "0-1000000000")!r}))
    """)
    run = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         timeout=300)
    assert run.returncode == 2, run.stderr[-2000:]
    assert "frames 4-1000000000 are not in the table" in run.stderr


def test_the_python_doors_read_ranges_as_ranges():
    from napari_pfsdm.analysis.classification import feature_matrix, frame_ranges, parse_frames

    assert frame_ranges("9-10, 0-1000000000000") == [(0, 1000000000000)]
    assert parse_frames("1-2,3", available=range(10)) == [1, 2, 3]
    with pytest.raises(InputError, match="frames 5-1000000000 are outside the movie's 0-4"):
        parse_frames("0-1000000000", n_frames=5)
    with pytest.raises(InputError, match="2,000,001 frames; no movie has so many"):
        parse_frames("0-2000000")
    t = pf.measure(ellipses(3, 4), n_fourier=4, n_radii=4)
    with pytest.raises(InputError, match="frame 3 is not in the table"):
        feature_matrix(t, "shape", "0,3", object_col="label")


# --------------------------------------------------------------------------------------------
# ids of any size the file holds
# --------------------------------------------------------------------------------------------

BIG = [7, 2**63 + 5, 2**64 - 1, 2**62, 3, 2**53 + 1, 9, 2**63 - 1]


def test_uint64_ids_come_through_every_command_exactly(tmp_path, capsys):
    movie = ellipses(3, 8, np.uint64, BIG)
    tifffile.imwrite(tmp_path / "u.tif", movie, photometric="minisblack")
    (tmp_path / "g.csv").write_text("label,group\n" + "".join(
        f"{lab},{'a' if i % 2 else 'b'}\n" for i, lab in enumerate(BIG)))
    f, g = str(tmp_path / "f.csv"), str(tmp_path / "g.csv")
    assert main(["measure", str(tmp_path / "u.tif"), "-o", f, "--link", "labels", "-q",
                 *FAST]) == 0
    t = pf.read_table(f)
    assert sorted(int(v) for v in set(t["label"])) == sorted(BIG)
    for argv in (["compare", f, "-o", str(tmp_path / "d.csv"), "--groups", g],
                 ["trajectories", f, "-o", str(tmp_path / "p.csv"), "--groups", g, "--plot",
                  str(tmp_path / "p.png")],
                 ["plot", f, "--column", "area", "-o", str(tmp_path / "a.png"), "--values",
                  str(tmp_path / "v.csv"), "--objects", f"u/{2**64 - 1}"],
                 ["report", f, "-o", str(tmp_path / "r.html"), "--labels",
                  str(tmp_path / "u.tif"), "--groups", g],
                 ["classify", f, "--groups", g, "--frames", "0-1", "--splits", "2",
                  "--test-size", "0.5", "--repeats", "1"]):
        assert main([*argv, "-q"]) == 0, (argv, capsys.readouterr().err)
    ids = pd.read_csv(tmp_path / "d.csv", index_col=0).index
    assert f"u/t0/l{2**64 - 1}" in ids and f"u/t2/l{2**63 + 5}" in ids
    scores = pf.read_table(tmp_path / "p.csv")
    assert {int(v) for v in scores["label"]} == set(BIG)
    groups = dict(zip((int(v) for v in scores["label"]), scores["group"], strict=True))
    assert groups[2**64 - 1] == "b" and groups[2**63 + 5] == "a"
    assert f"{2**64 - 1}" in (tmp_path / "r.html").read_text()


def test_pairs_of_large_ids_and_frames_are_matched_exactly():
    """(frame, label) pairs whose product overflowed int64 (ids near 2**62, frames above 1)."""
    from napari_pfsdm.analysis.tables import key_rows

    labels = np.array([1, 2**62, 2**62 + 1, 2**64 - 1], dtype=np.uint64)
    frames = np.array([3, 3, 2, 5])
    at = np.array([3, 0, 1, 2])
    got = key_rows(frames[[1, 2, 0]], labels[[1, 2, 0]], frames[at], labels[at])
    assert got.tolist() == [2, 3, 1]  # at[2] = (3, 2**62), at[3] = (2, 2**62 + 1), at[1] = (3, 1)
    assert key_rows([2], [2**62], [3], [2**62]).tolist() == [-1]
    # frame 4, label 1 is not (0, 1): 4 * 2**62 wrapped to 0 in int64 made them one pair
    assert key_rows([4, 0], [1, 1], [0, 4], [1, 2**62]).tolist() == [-1, 0]


# --------------------------------------------------------------------------------------------
# seeds, workers and every number a command takes
# --------------------------------------------------------------------------------------------

@pytest.mark.parametrize("seed", ["-1", str(2**31), str(2**64), "1.5", "x"])
def test_a_seed_out_of_range_is_refused_in_words(table, capsys, seed):
    for command in ("classify", "predict"):
        with pytest.raises(SystemExit) as info:
            main([*_frames_argv(command, table, "0-1"), "--seed", seed])
        assert info.value.code == 2
        assert "--seed must be a whole number from 0 to 2,147,483,647" in error_line(capsys)


def test_seeds_are_checked_in_python_too():
    from napari_pfsdm.analysis.outcome import predict_outcome
    from napari_pfsdm.analysis.prediction import make_splits

    y = np.array([0, 1] * 5)
    assert len(make_splits(y, n_splits=2, n_repeats=1, seed=2**31 - 1)) == 2
    with pytest.raises(InputError, match="seed must be a whole number"):
        make_splits(y, seed=-1)
    with pytest.raises(InputError, match="at most 10,000 splits in all"):
        make_splits(y, n_splits=1000, n_repeats=11)
    t = pf.measure(ellipses(2, 8), n_fourier=4, n_radii=4)
    with pytest.raises(InputError, match="seed must be a whole number"):
        predict_outcome(t, {i: "ab"[i % 2] for i in range(1, 9)}, seed=2**40)


def test_workers_are_at_most_the_cores(table, tmp_path, capsys):
    from napari_pfsdm.analysis.schedulers import available_cores, process_pool
    from napari_pfsdm.batch.movies import Movie
    from napari_pfsdm.batch.run import run_batch

    cores = available_cores()
    with pytest.raises(SystemExit):
        main(["measure", str(table / "m.tif"), "-o", str(tmp_path / "o.csv"), "--workers",
              str(cores + 1), "-q"])
    line = error_line(capsys)
    assert f"--workers {cores + 1}: this machine offers {cores} core" in line
    assert f"at most {cores}" in line
    with pytest.raises(InputError, match=f"num_workers {cores + 1}: this machine offers"):
        run_batch([Movie("m", table / "m.tif")], tmp_path / "o.csv", num_workers=cores + 1)
    with pytest.raises(InputError, match=f"workers {cores + 1}: this machine offers"):
        process_pool(cores + 1)
    assert not (tmp_path / "o.csv").exists()


def test_every_numeric_option_of_the_record_is_bounded():
    from napari_pfsdm.core.params import OPTIONS

    for opt in OPTIONS:
        if opt.kind in (int, float) and not opt.choices:
            assert opt.low is not None and opt.high is not None, opt.name


#: Numbers a command takes that only the data bound, each with the test of its bound.
BOUNDED_BY_THE_DATA = {
    "--neighbours": "test_numbers_the_data_bound_are_refused_above_it",
    "--components": "test_numbers_the_data_bound_are_refused_above_it",
    "--show": "test_show_beyond_the_components_is_refused (test_faults_files.py)",
    "--series": "test_a_series_that_does_not_exist_is_refused (test_faults_files.py)",
    "--at": "a time no object has is refused (test_pfsdm_stats_prints_the_findings_and_"
            "writes_the_table, test_group_stats.py)",
    "--rerank-k": "used as min(K, objects - 1): documented in pfsdm compare -h",
    "--spacing": "the three sides checked together before any work "
                 "(test_a_voxel_size_that_would_overflow_is_refused, test_faults_files.py)",
}


def _number_actions():
    sub = next(a for a in build_parser()._actions if isinstance(a, argparse._SubParsersAction))
    for name, parser in sub.choices.items():
        for action in parser._actions:
            if not action.option_strings or action.type is None or action.choices:
                continue
            try:
                action.type("12")
            except (argparse.ArgumentTypeError, ValueError, TypeError):
                continue  # not a number
            yield name, action


def test_every_number_a_command_takes_is_bounded():
    """Every option that takes a number refuses 10⁴⁰ as it parses, or is bounded by the data
    (and then has a test of that bound)."""
    found = 0
    for _command, action in _number_actions():
        flag = action.option_strings[-1]
        found += 1
        if flag in BOUNDED_BY_THE_DATA:
            continue
        with pytest.raises((argparse.ArgumentTypeError, ValueError)):
            action.type(str(10**40))
        with pytest.raises((argparse.ArgumentTypeError, ValueError)):
            action.type("-1e400")
    assert found > 20


def test_numbers_the_data_bound_are_refused_above_it(table, capsys):
    f = str(table / "f.csv")
    assert main(["compare", f, "--neighbours", str(10**30), "-o",
                 str(table / "e.csv"), "-q"]) == 2
    assert "each has at most 31 neighbours" in error_line(capsys)
    assert main(["trajectories", f, "--components", "1000", "-o", str(table / "p.csv"),
                 "-q"]) == 2
    line = error_line(capsys)
    assert "--components 1000: the 32 rows of the table give at most" in line
    assert not (table / "p.csv").exists()


def test_a_min_area_beyond_any_image_is_refused(table, tmp_path, capsys):
    with pytest.raises(SystemExit):
        main(["measure", str(table / "m.tif"), "-o", str(tmp_path / "o.csv"), "--min-area",
              str(10**23), "-q"])
    assert "min_area must be" in error_line(capsys)
    with pytest.raises(InputError, match="min_area"):
        pf.measure(ellipses(1, 2)[0], min_area=10**23)


def test_a_matrix_beyond_the_machines_memory_is_refused(table, capsys):
    from napari_pfsdm.cli.compare import _matrix_limit

    limit = _matrix_limit()
    if limit is None:
        pytest.skip("the machine's memory cannot be read here")
    memory = os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
    assert 8 * limit**2 < memory  # the matrix alone fits
    with pytest.raises(SystemExit):
        main(["compare", str(table / "f.csv"), "-o", str(table / "d.csv"), "--max-objects",
              str(limit + 1)])
    assert "would not fit in this machine's memory" in error_line(capsys)
