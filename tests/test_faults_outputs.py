"""The fault battery, round 3 (issue 66), rules 1 and 3: nothing the user owns is replaced,
and the outputs of one command never collide with each other or with an input.

Neither test lists the files by hand. The first runs every command of ``pfsdm`` once, finds
every file it writes (the directory before and after), then plants a user's own file at each
of those names in turn: the command must stop with a message naming it, leave it as it was
and write nothing else. The second walks the files each command declares
(``cli.common.file_argument``): every pair of its outputs given one name (as written, through
``..``, through a link, in another case where the file system folds case), and every output
given the name of one of its inputs or of an input table's sidecar, must be refused before
any work. A command added without a recipe here fails :func:`test_every_command_has_a_recipe`.
"""

from __future__ import annotations

import argparse
import itertools
import os
from pathlib import Path

import numpy as np
import pytest
import tifffile

from napari_pfsdm.cli import build_parser, main
from napari_pfsdm.cli.common import declared_files
from shapes_fixture import drifting_ellipses

FAST = ["--n-fourier", "4", "--n-radii", "4", "--scheduler", "sync"]
MINE = b"my own notes, not pfsdm's\n"


def ellipses(n_frames: int = 3, n: int = 8) -> np.ndarray:
    """``n`` ellipses (two kinds: round and long) drifting right, ids that follow them."""
    return drifting_ellipses(n_frames, n)


@pytest.fixture(scope="module")
def src(tmp_path_factory) -> Path:
    """A label movie, its feature table and a groups file, in a folder of their own."""
    folder = tmp_path_factory.mktemp("inputs")
    tifffile.imwrite(folder / "m.tif", ellipses(), photometric="minisblack")
    assert main(["measure", str(folder / "m.tif"), "-o", str(folder / "f.csv"), "--link",
                 "labels", "-q", *FAST]) == 0
    (folder / "g.csv").write_text("label,group\n" + "".join(
        f"{i},{'round' if i % 2 == 0 else 'long'}\n" for i in range(1, 9)))
    return folder


#: Every command that writes, with every output it can write: argv from (inputs, out folder).
RECIPES = {
    "measure": lambda s, o: ["measure", str(s / "m.tif"), "-o", str(o / "o.csv"), "--link",
                             "labels", "-q", *FAST],
    "compare": lambda s, o: ["compare", str(s / "f.csv"), "-o", str(o / "d.csv"), "--mds",
                             str(o / "map.png"), "--groups", str(s / "g.csv"), "-q"],
    "compare --neighbours": lambda s, o: ["compare", str(s / "f.csv"), "--neighbours", "2",
                                          "-o", str(o / "e.csv"), "--mds", str(o / "n.png"),
                                          "-q"],
    "trajectories": lambda s, o: ["trajectories", str(s / "f.csv"), "-o", str(o / "p.csv"),
                                  "--plot", str(o / "p.png"), "--groups", str(s / "g.csv"),
                                  "-q"],
    "classify": lambda s, o: ["classify", str(s / "f.csv"), "--groups", str(s / "g.csv"),
                              "--frames", "0-1", "--splits", "2", "--test-size", "0.5",
                              "--repeats", "1", "-o", str(o / "s.csv"), "-q"],
    "predict": lambda s, o: ["predict", str(s / "f.csv"), "--groups", str(s / "g.csv"),
                             "--frames", "0", "--splits", "2", "--repeats", "1", "-o",
                             str(o / "pr.csv"), "-q"],
    "predict --on": lambda s, o: ["predict", str(s / "f.csv"), "--groups", str(s / "g.csv"),
                                  "--frames", "0", "--on", str(s / "f.csv"), "-o",
                                  str(o / "on.csv"), "-q"],
    "stats": lambda s, o: ["stats", str(s / "f.csv"), "--groups", str(s / "g.csv"),
                           "--measure", "area", "-o", str(o / "st.csv"), "--objects",
                           str(o / "ob.csv"), "-q"],
    "plot": lambda s, o: ["plot", str(s / "f.csv"), "--column", "area", "-o",
                          str(o / "a.png"), "--values", str(o / "v.csv"), "-q"],
    "report": lambda s, o: ["report", str(s / "f.csv"), "-o", str(o / "r.html"), "--labels",
                            str(s / "m.tif"), "--groups", str(s / "g.csv"), "-q"],
    "demo": lambda s, o: ["demo", "--quick-only", "-o", str(o / "res"), "--scheduler",
                          "sync", "-q"],
}
#: Commands that write nothing (none today).
READ_ONLY: set[str] = set()


def listing(folder: Path) -> dict[str, bytes | None]:
    """Every file and folder under ``folder``: its bytes (None for a folder)."""
    out: dict[str, bytes | None] = {}
    for root, dirs, files in os.walk(folder):
        for d in dirs:
            out[os.path.relpath(os.path.join(root, d), folder)] = None
        for f in files:
            out[os.path.relpath(os.path.join(root, f), folder)] = Path(root, f).read_bytes()
    return out


def error_line(capsys) -> str:
    err = capsys.readouterr().err
    assert "Traceback" not in err and "internal error" not in err, err
    lines = [ln for ln in err.splitlines() if ln.startswith("pfsdm: error:")]
    assert len(lines) == 1, err
    return lines[0]


def commands() -> set[str]:
    sub = next(a for a in build_parser()._actions if isinstance(a, argparse._SubParsersAction))
    return set(sub.choices)


def test_every_command_has_a_recipe():
    named = {name.split()[0] for name in RECIPES} | READ_ONLY
    assert commands() == named, ("a command without a recipe in RECIPES: give it one, with "
                                 "every output it can write")


@pytest.fixture(scope="module")
def written(src, tmp_path_factory) -> dict[str, list[str]]:
    """What each recipe writes, found by running it (files and folders, relative; a folder's
    name ends with the separator)."""
    found = {}
    for name, recipe in RECIPES.items():
        out = tmp_path_factory.mktemp("first")
        assert main(recipe(src, out)) == 0, name
        found[name] = sorted(rel + (os.sep if data is None else "")
                             for rel, data in listing(out).items())
    return found


def test_every_file_a_command_writes_is_one_it_declares(src, written, tmp_path):
    """The declaration the checks read (cli.common.file_argument) covers every file written."""
    for name, recipe in RECIPES.items():
        args = build_parser().parse_args(recipe(src, tmp_path))
        outputs, _ = declared_files(args)
        covered = set()
        for out in outputs:
            for f in out.files():
                covered.add(os.path.relpath(f, tmp_path))
        for rel in written[name]:
            rel = rel.rstrip(os.sep)
            inside = any(rel == c or rel.startswith(c + os.sep) for c in covered)
            assert inside, f"{name} wrote {rel}, which no declared output covers"


@pytest.mark.parametrize("name", sorted(RECIPES))
def test_no_command_replaces_a_users_file(src, written, tmp_path, capsys, name):
    recipe = RECIPES[name]
    assert written[name], f"{name} wrote nothing"
    for i, rel in enumerate(written[name]):
        out = tmp_path / f"case{i}"
        rel = rel.rstrip(os.sep)  # a file where the command makes a folder, too
        theirs = out / rel
        theirs.parent.mkdir(parents=True, exist_ok=True)
        theirs.write_bytes(MINE)
        before = listing(out)
        rc = main(recipe(src, out))
        assert theirs.read_bytes() == MINE, f"{name} replaced the user's {rel}"
        if name == "demo" and ".parts" + os.sep in rel:
            continue  # a part's name holds its movie's path: here another name, untouched
        assert rc == 2, f"{name} went on with the user's {rel} in the way"
        line = error_line(capsys)
        assert theirs.name in line, line
        if os.sep not in rel or name == "demo" and rel.count(os.sep) == 1:
            assert listing(out) == before, f"{name} wrote files before refusing ({rel})"
    # --force replaces them (every top-level name taken at once), and a second run without
    # it replaces the command's own files
    out = tmp_path / "all"
    depth = 1 if name == "demo" else 0  # the demo's files are inside its folder
    top = [rel for rel in written[name]
           if rel.count(os.sep) == depth and not rel.endswith(os.sep)]  # files, not folders
    for rel in top:
        (out / rel).parent.mkdir(parents=True, exist_ok=True)
        (out / rel).write_bytes(MINE)
    assert main([*recipe(src, out), "--force"]) == 0
    assert all((out / rel).is_dir() or (out / rel).read_bytes() != MINE for rel in top)
    assert main(recipe(src, out)) == 0


def _outputs(src: Path, name: str, out: Path) -> tuple[list[str], argparse.Namespace]:
    argv = RECIPES[name](src, out)
    args = build_parser().parse_args(argv)
    return argv, args


def _replace(argv: list[str], old: str, new: str) -> list[str]:
    assert argv.count(old) == 1, (old, argv)
    return [new if a == old else a for a in argv]


@pytest.mark.parametrize("name", sorted(RECIPES))
def test_two_outputs_of_one_command_never_share_a_file(src, tmp_path, capsys, name):
    out = tmp_path / "w"
    out.mkdir()
    argv, args = _outputs(src, name, out)
    outputs, _ = declared_files(args)
    named = [o for o in outputs if str(o.path) in argv]
    pairs = list(itertools.permutations(named, 2))
    if len(named) < 2:
        pytest.skip(f"{name} writes one named output")
    (out / "sub").mkdir()
    for a, b in pairs:
        spellings = [str(a.path), str(out / "sub" / ".." / a.path.name)]
        if a.kind == "table":
            spellings.append(str(a.path) + ".json")  # the other output over a's sidecar
        for spelling in spellings:
            if b.kind == "folder" or a.kind == "folder":
                continue
            before = listing(out)
            assert main(_replace(argv, str(b.path), spelling)) == 2, (name, b.name, spelling)
            line = error_line(capsys)
            assert "one file" in line and b.name in line, line
            assert listing(out) == before


@pytest.mark.parametrize("name", sorted(RECIPES))
def test_no_output_is_an_input_or_its_sidecar(src, tmp_path, capsys, name):
    out = tmp_path / "w"
    out.mkdir()
    argv, args = _outputs(src, name, out)
    outputs, inputs = declared_files(args)
    copies = tmp_path / "inputs"
    if not inputs:
        pytest.skip(f"{name} reads no file")
    tried = 0
    for o in (o for o in outputs if str(o.path) in argv and o.kind != "folder"):
        for i in inputs:
            targets = [i.path] + ([Path(str(i.path) + ".json")] if i.kind == "table" else [])
            for target in targets:
                if not target.exists():
                    continue
                kept = target.read_bytes()
                for force in ([], ["--force"]):
                    assert main(_replace(argv, str(o.path), str(target)) + force) == 2
                    line = error_line(capsys)
                    assert "input" in line and target.name in line, line
                    assert target.read_bytes() == kept
                    tried += 1
    assert tried, name
    del copies


def test_a_link_to_an_input_is_the_input(src, tmp_path, capsys):
    link = tmp_path / "link.csv"
    link.symlink_to(src / "f.csv")
    hard = tmp_path / "hard.csv"
    os.link(src / "f.csv", hard)
    kept = (src / "f.csv").read_bytes()
    for alias in (link, hard):
        assert main(["trajectories", str(src / "f.csv"), "-o", str(alias), "-q",
                     "--force"]) == 2
        assert "is also an input" in error_line(capsys)
    assert (src / "f.csv").read_bytes() == kept


def test_outputs_that_differ_only_in_case_collide_where_the_file_system_folds_case(
        src, tmp_path, capsys, monkeypatch):
    from napari_pfsdm.io import outputs

    probe_case, _ = outputs.folds_case(tmp_path)
    (tmp_path / "x").write_text("lower")
    assert (tmp_path / "X").exists() == probe_case  # what the probe says is what it is
    # here (Linux) names differ by case: two files, both written
    argv = ["trajectories", str(src / "f.csv"), "-o", str(tmp_path / "P.csv"), "--plot",
            str(tmp_path / "p.csv"), "-q"]
    if not probe_case:
        assert main(argv) == 0
        assert (tmp_path / "P.csv").read_bytes()[:4] != b"\x89PNG"
        # where the file system folds case (macOS, Windows) they are one file: refused
        monkeypatch.setattr(outputs, "folds_case", lambda folder: (True, False))
        for other in ("Q.CSV", "q.Csv", "Q.csv"):
            argv = ["trajectories", str(src / "f.csv"), "-o", str(tmp_path / "q.csv"),
                    "--plot", str(tmp_path / other), "-q", "--force"]
            assert main(argv) == 2
            line = error_line(capsys)
            assert "one file" in line and "upper and lower case" in line
        assert not (tmp_path / "q.csv").exists()
        # an output spelled in another case than an existing input is that input: refused
        assert main(["trajectories", str(src / "f.csv"), "-o", str(src / "F.CSV"), "-q",
                     "--force"]) == 2
        assert "is also an input" in error_line(capsys)


def test_an_output_inside_an_input_zarr_store_is_refused(tmp_path, capsys):
    zarr = pytest.importorskip("zarr")
    store = tmp_path / "m.zarr"
    arr = zarr.create_array(str(store), shape=(2, 96, 160), dtype="uint16",
                            chunks=(1, 96, 160))
    arr[:] = ellipses(2)
    before = listing(store)
    assert main(["measure", str(store), "-o", str(store / "f.csv"), "-q", *FAST]) == 2
    assert "inside the input movie" in error_line(capsys)
    assert listing(store) == before


def test_python_doors_check_their_outputs_too(src, tmp_path):
    """save_analysis and the plugin's export name their files from the user's words: the
    names are checked as the commands' outputs are (no file outside the folder, no two
    outputs one file)."""
    import napari_pfsdm as pf
    from napari_pfsdm.io import Output, check_outputs

    table = pf.read_table(src / "f.csv")
    with pytest.raises(ValueError, match="one file"):
        check_outputs([Output(tmp_path / "a.csv"), Output(tmp_path / "a.csv.json", "file")])
    with pytest.raises(ValueError, match="already exists and was not written by pfsdm"):
        (tmp_path / "s").mkdir()
        (tmp_path / "s" / "boxes.csv").write_bytes(MINE)
        from napari_pfsdm.saved import save_analysis

        save_analysis(tmp_path / "s", table)
    assert (tmp_path / "s" / "boxes.csv").read_bytes() == MINE


@pytest.mark.parametrize("parts", ["o.csv", "o.csv.json", "m.tif"])
def test_the_parts_folder_is_an_output_too(src, tmp_path, capsys, parts):
    where = src if parts == "m.tif" else tmp_path
    kept = listing(src)
    assert main(["measure", str(src / "m.tif"), "-o", str(tmp_path / "o.csv"), "--parts",
                 str(where / parts), "-q", *FAST]) == 2
    line = error_line(capsys)
    assert "--parts" in line and ("one file" in line or "input" in line), line
    assert listing(src) == kept and not (tmp_path / "o.csv").exists()


@pytest.mark.parametrize("layer", ["../outside", "a/b", "c:d", ".hidden", ""])
def test_the_plugins_export_takes_a_layer_name_as_data(src, tmp_path, layer):
    """The export names its files from the layer's name: never a path out of the chosen
    folder, never a hidden file; a user's file of one of its names is kept."""
    pytest.importorskip("psygnal")
    import napari_pfsdm as pf
    from napari_pfsdm.napari import _export
    from napari_pfsdm.napari._model import Analysis

    folder = tmp_path / "export"
    table = pf.read_table(src / "f.csv")
    paths, _ = _export.export(Analysis("A", 1, table, {}, axes="tyx"), folder, layer)
    assert paths and all(p.parent == folder and not p.name.startswith(".") for p in paths)
    assert sorted(os.listdir(tmp_path)) == ["export"]
    theirs = paths[1]
    theirs.write_bytes(MINE)
    with pytest.raises(ValueError, match="not written by pfsdm"):
        _export.export(Analysis("A", 1, table, {}, axes="tyx"), folder, layer)
    assert theirs.read_bytes() == MINE


def test_a_table_the_user_edited_after_pfsdm_wrote_it_is_theirs(src, tmp_path, capsys):
    """A cell corrected by hand (the table saved after its sidecar): a re-run does not
    replace the edit without --force; a table pfsdm wrote, untouched, it replaces."""
    out = tmp_path / "p.csv"
    argv = ["trajectories", str(src / "f.csv"), "-o", str(out), "-q"]
    assert main(argv) == 0 and main(argv) == 0
    edited = out.read_text().replace(",0,", ",0.5,", 1)
    out.write_text(edited)
    t = os.stat(out.with_name("p.csv.json")).st_mtime_ns + 10**9
    os.utime(out, ns=(t, t))
    assert main(argv) == 2
    assert "p.csv already exists and was not written by pfsdm" in error_line(capsys)
    assert out.read_text() == edited
    assert main([*argv, "--force"]) == 0 and out.read_text() != edited
