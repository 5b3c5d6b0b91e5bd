"""The npe2 manifest: valid, importable, carried in the wheel and discovered after install."""

from __future__ import annotations

import json
import site
import subprocess
import sys
import zipfile
from pathlib import Path

import numpy as np
import pytest

npe2 = pytest.importorskip("npe2")

ROOT = Path(__file__).resolve().parents[2]
MANIFEST = ROOT / "napari.yaml"


def test_manifest_is_valid_and_its_commands_import():
    mf = npe2.PluginManifest.from_file(MANIFEST)
    mf.validate_imports()
    assert mf.name == "napari-pfsdm"
    widgets = {w.display_name for w in mf.contributions.widgets}
    assert widgets == {"PF-SDM analysis", "PF-SDM plots", "PF-SDM prediction", "PF-SDM study"}
    assert [s.key for s in mf.contributions.sample_data] == ["gastruloids", "five_shapes"]
    menus = mf.contributions.menus
    assert {"napari/layers/measure", "napari/layers/visualize", "napari/layers/classify"} \
        <= set(menus)
    # label TIFFs and Zarr stores open as Labels layers (File > Open, drag and drop)
    (reader,) = mf.contributions.readers
    assert reader.command == "napari-pfsdm.read_labels" and reader.accepts_directories
    assert {"*.tif", "*.tiff", "*.zarr"} <= set(reader.filename_patterns)
    # several movies measured as one study: beside the analysis, Layers > Measure
    assert [m.command for m in menus["napari/layers/measure"]] == [
        "napari-pfsdm.analysis_widget", "napari-pfsdm.study"]
    # prediction is a classifier: napari's Layers > Classify
    assert [m.command for m in menus["napari/layers/classify"]] == ["napari-pfsdm.prediction"]
    # the package's copy is the same file (a symlink in the source tree)
    packaged = ROOT / "src" / "napari_pfsdm" / "napari.yaml"
    assert packaged.read_text() == MANIFEST.read_text()


def test_installed_plugin_is_discovered():
    pm = npe2.PluginManager.instance()
    pm.discover()
    mf = pm.get_manifest("napari-pfsdm")
    assert len(mf.contributions.widgets) == 4


def test_sample_data_is_deterministic_and_small():
    from napari_pfsdm.napari._sample_data import benchmark_shapes, gastruloid_timelapse

    first = gastruloid_timelapse()
    again = gastruloid_timelapse()
    shapes = benchmark_shapes()
    (image, _, kind_i), (labels, meta, kind_l) = first
    assert (kind_i, kind_l) == ("image", "labels")
    assert labels.ndim == 3 and labels.shape == image.shape
    np.testing.assert_array_equal(labels, again[1][0])
    groups = meta["metadata"]["groups"]
    assert set(groups.values()) == {"single-axis", "multi-axes"}
    assert set(np.unique(labels)) - {0} == set(groups)
    (shape_labels, smeta, kind) = shapes[0]
    assert kind == "labels" and shape_labels.ndim == 2
    assert len(np.unique(shape_labels)) - 1 == len(smeta["metadata"]["groups"]) == 20


CHECK = """
import json, npe2, napari_pfsdm
pm = npe2.PluginManager.instance(); pm.discover()
mf = pm.get_manifest("napari-pfsdm")
print(json.dumps({"file": napari_pfsdm.__file__,
                  "widgets": [w.display_name for w in mf.contributions.widgets],
                  "samples": [s.key for s in mf.contributions.sample_data],
                  }))
"""


@pytest.mark.slow
def test_wheel_carries_the_manifest_and_a_fresh_install_finds_the_plugin(tmp_path):
    dist = tmp_path / "dist"
    build = subprocess.run([sys.executable, "-m", "build", "--wheel", "--outdir", str(dist),
                            str(ROOT)], capture_output=True, text=True, timeout=600)
    assert build.returncode == 0, build.stdout[-2000:] + build.stderr[-2000:]
    (wheel,) = dist.glob("napari_pfsdm-*.whl")
    with zipfile.ZipFile(wheel) as zf:
        assert zf.read("napari_pfsdm/napari.yaml") == MANIFEST.read_bytes()
        # every subpackage of the source tree ships (a folder without __init__.py would not)
        names = set(zf.namelist())
        for init in (ROOT / "src" / "napari_pfsdm").rglob("*.py"):
            rel = init.relative_to(ROOT / "src").as_posix()
            assert rel in names, f"{rel} is missing from the wheel"
        entry = next(n for n in zf.namelist() if n.endswith(".dist-info/entry_points.txt"))
        assert "napari-pfsdm = napari_pfsdm:napari.yaml" in zf.read(entry).decode()
    env = tmp_path / "env"
    subprocess.run([sys.executable, "-m", "venv", "--without-pip", str(env)], check=True,
                   timeout=300)
    py = env / "bin" / "python"
    purelib = subprocess.run([str(py), "-c", "import sysconfig; print(sysconfig.get_path("
                              "'purelib'))"], capture_output=True, text=True, check=True)
    target = Path(purelib.stdout.strip())
    # the fresh environment borrows the dependencies (numpy, napari, npe2...) of this one
    # but not its editable napari-pfsdm: only a path line, whose .pth files are not run
    deps = [p for p in site.getsitepackages() if Path(p).is_dir()]
    (target / "_borrowed_deps.pth").write_text("\n".join(deps) + "\n")
    pip = subprocess.run([sys.executable, "-m", "pip", "--python", str(py), "install",
                          "--no-deps", "--no-index", str(wheel)], capture_output=True,
                         text=True, timeout=600)
    assert pip.returncode == 0, pip.stdout[-2000:] + pip.stderr[-2000:]
    out = subprocess.run([str(py), "-c", CHECK], capture_output=True, text=True, timeout=300,
                         cwd=tmp_path)
    assert out.returncode == 0, out.stderr[-3000:]
    found = json.loads(out.stdout.strip().splitlines()[-1])
    assert found["file"].startswith(str(env)), found["file"]
    assert "PF-SDM analysis" in found["widgets"]
    assert found["samples"] == ["gastruloids", "five_shapes"]
