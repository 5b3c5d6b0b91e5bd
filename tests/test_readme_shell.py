"""Every `pfsdm ...` line of README.md's ```bash blocks runs as written, on a folder laid out as
the lines imply: label movies and their `*_reporter.tif` side by side in `movies/`, a
`groups.csv`, and a `stacks/` folder of 3-D time-lapses. Only the line that needs a
dask.distributed cluster (`--scheduler tcp://...`) is left out, and a Parquet line when pyarrow
is missing."""

from __future__ import annotations

import importlib.util
import os
import re
import shlex
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import tifffile

from napari_pfsdm.batch.movies import find_movies, pair_movies
from napari_pfsdm.data.gastruloids import make_timelapse_montage
from napari_pfsdm.data.volumes import blob_volume

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"
SHELL_BLOCKS = re.findall(r"^```(?:bash|sh|shell|console)\n(.*?)^```",
                          README.read_text(encoding="utf-8"), re.S | re.M)
COMMANDS = [shlex.split(line, comments=True)
            for block in SHELL_BLOCKS for line in block.splitlines()
            if line.strip().startswith("pfsdm ")]
OUTPUT_OPTIONS = ("-o", "--output", "--plot", "--mds")


def _lay_out(folder: Path) -> None:
    """The folder the README's examples imply, small enough to measure in seconds."""
    (folder / "movies").mkdir()
    rows = []
    for i, seed in enumerate((0, 1), start=1):
        labels, reporter, groups = make_timelapse_montage(n_objects=4, n_frames=12, size=128,
                                                          seed=seed)
        tifffile.imwrite(folder / "movies" / f"e{i:02d}.tif", labels)
        tifffile.imwrite(folder / "movies" / f"e{i:02d}_reporter.tif", reporter)
        rows += [{"movie": f"e{i:02d}", "label": k, "group": g} for k, g in groups.items()]
    pd.DataFrame(rows).to_csv(folder / "groups.csv", index=False)
    days = [1, 2, 3, 5, 5, 7, 9, 12, 14, 17, 20, 24]  # uneven, one day twice
    pd.DataFrame([{"movie": f"e{i:02d}.tif", "frame": t, "time": d} for i in (1, 2)
                  for t, d in enumerate(days)]).to_csv(folder / "times.csv", index=False)
    (folder / "stacks").mkdir()
    spacing = (2.0, 0.5, 0.5)
    stack = np.zeros((2, 16, 40, 80), np.uint16)  # T × Z × Y × X, two objects
    for t in range(2):
        stack[t, :, :, :40][blob_volume("tetrahedron", size=(16, 40, 40), radius=14 + t,
                                        spacing=spacing)] = 1
        stack[t, :, :, 40:][blob_volume("line", size=(16, 40, 40), radius=14 + t,
                                        spacing=spacing)] = 2
    tifffile.imwrite(folder / "stacks" / "nuclei01.tif", stack)


def _outputs(argv: list[str]) -> list[str]:
    return [argv[i + 1] for i, a in enumerate(argv[:-1]) if a in OUTPUT_OPTIONS]


def test_readme_has_command_lines():
    assert len(COMMANDS) >= 5, "README.md's ```bash blocks hold no pfsdm command lines"
    assert any(a == "--intensity" for argv in COMMANDS for a in argv)


def test_readme_command_lines_run(tmp_path):
    """The lines run in order (later ones read earlier ones' tables) and each output is there
    and readable: CSV by pandas.read_csv with no arguments, Parquet by pandas.read_parquet."""
    _lay_out(tmp_path)
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(
        [str(ROOT / "src"), *filter(None, [os.environ.get("PYTHONPATH")])])}
    ran = 0
    for argv in COMMANDS:
        if any(a.startswith("tcp://") for a in argv):
            continue  # needs a running dask.distributed scheduler
        outputs = _outputs(argv)
        if any(o.endswith(".parquet") for o in outputs) and \
                importlib.util.find_spec("pyarrow") is None:
            continue  # the [parquet] extra
        proc = subprocess.run([sys.executable, "-m", "napari_pfsdm", *argv[1:]], cwd=tmp_path,
                              env=env, capture_output=True, text=True, timeout=600)
        assert proc.returncode == 0, f"{shlex.join(argv)} failed:\n{proc.stderr[-3000:]}"
        for out in outputs:
            path = tmp_path / out
            assert path.is_file(), f"{shlex.join(argv)} did not write {out}"
            if out.endswith(".csv"):
                assert len(pd.read_csv(path)) > 0, out
                assert path.with_name(path.name + ".json").is_file(), f"{out} has no sidecar"
            elif out.endswith(".parquet"):
                assert len(pd.read_parquet(path)) > 0, out
        ran += 1
    assert ran >= 5


def test_reporters_given_as_intensity_are_not_label_movies(tmp_path):
    """`pfsdm measure movies/ --intensity 'movies/*_reporter.tif'`: the reporters sit in the
    labels' folder; they pair with the label movies and are not measured as labels."""
    for name in ("a.tif", "a_reporter.tif", "b.tif", "b_reporter.tif"):
        (tmp_path / name).write_bytes(b"")
    labels = find_movies(tmp_path)
    reporters = find_movies(str(tmp_path / "*_reporter.tif"))
    assert len(labels) == 4 and len(reporters) == 2
    movies = pair_movies(labels, reporters)
    assert [(m.name, m.labels.name, m.intensity.name) for m in movies] == [
        ("a", "a.tif", "a_reporter.tif"), ("b", "b.tif", "b_reporter.tif")]
    # the same file as the only label movie and the intensity stays as given
    one = pair_movies([tmp_path / "a.tif"], [tmp_path / "a.tif"])
    assert [(m.labels.name, m.intensity.name) for m in one] == [("a.tif", "a.tif")]
    # without --intensity nothing is dropped
    assert len(pair_movies(labels)) == 4


@pytest.mark.parametrize("text", ["Plugins ▸ PF-SDM morphometrics ▸",
                                  "File ▸ Open Sample ▸ PF-SDM morphometrics ▸"])
def test_readme_menu_paths_name_the_plugin_as_napari_shows_it(text):
    manifest = (ROOT / "src" / "napari_pfsdm" / "napari.yaml").read_text(encoding="utf-8")
    assert "display_name: PF-SDM morphometrics" in manifest
    readme = README.read_text(encoding="utf-8")
    assert text in readme
    assert "▸ napari-pfsdm ▸" not in readme
