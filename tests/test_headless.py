"""The library, the analysis, the data, the batch, the CLI and the paper's reproductions
(``examples/``, imported as ``pfsdm demo`` imports them) import no Qt, napari or magicgui."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

FORBIDDEN = ("qtpy", "PyQt5", "PyQt6", "PySide2", "PySide6", "napari", "magicgui", "vispy",
             "superqt")

MODULES = [
    "napari_pfsdm",
    "napari_pfsdm.core",
    "napari_pfsdm.analysis",
    "napari_pfsdm.analysis.features",
    "napari_pfsdm.data",
    "napari_pfsdm.data.shapes",
    "napari_pfsdm.data.gastruloids",
    "napari_pfsdm.batch",
    "napari_pfsdm.cli",
    "napari_pfsdm.io",
]

#: The folder of the paper's reproductions, and their modules (outside the package).
EXAMPLES = Path(__file__).resolve().parents[1] / "examples"
EXAMPLE_MODULES = sorted(p.stem for p in EXAMPLES.glob("*.py"))

SCRIPT = """
import importlib, json, pkgutil, sys
sys.path.insert(0, {examples!r})
import napari_pfsdm
names = {names!r}
# every submodule outside the napari plugin subpackage, too
for pkg in ("napari_pfsdm.core", "napari_pfsdm.analysis", "napari_pfsdm.cli",
            "napari_pfsdm.data", "napari_pfsdm.batch", "napari_pfsdm.io"):
    mod = importlib.import_module(pkg)
    names += [m.name for m in pkgutil.walk_packages(mod.__path__, pkg + ".")]
for name in names:
    importlib.import_module(name)
bad = sorted(m for m in sys.modules if m.split(".")[0] in {forbidden!r})
print(json.dumps({{"imported": sorted(set(names)), "bad": bad}}))
"""


def test_headless_modules_import_no_gui_toolkit():
    code = SCRIPT.format(names=MODULES + EXAMPLE_MODULES, forbidden=set(FORBIDDEN),
                         examples=str(EXAMPLES))
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         timeout=300, env={"PATH": "/usr/bin:/bin", "QT_API": "pyqt6"})
    assert out.returncode == 0, out.stderr
    result = json.loads(out.stdout.strip().splitlines()[-1])
    assert "napari_pfsdm.cli" in result["imported"]
    assert "napari_pfsdm.cli.demo" in result["imported"]
    assert "napari_pfsdm.io.sidecar" in result["imported"]
    assert {"gastruloid_report", "synthetic_five_shapes", "pixel_baseline"} <= set(
        result["imported"])
    assert "napari_pfsdm.core" in result["imported"]
    assert result["bad"] == [], f"GUI modules imported headless: {result['bad'][:10]}"


def test_the_check_would_notice_a_gui_import():
    """The subprocess check itself works: importing the plugin pulls in napari and Qt."""
    pytest.importorskip("napari")  # without napari there is nothing to show (skipped, said so)
    code = SCRIPT.format(names=["napari_pfsdm.napari._analysis"], forbidden=set(FORBIDDEN),
                         examples=str(EXAMPLES))
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         timeout=300)
    assert out.returncode == 0, out.stderr
    result = json.loads(out.stdout.strip().splitlines()[-1])
    assert "napari" in result["bad"] and "qtpy" in result["bad"]


def test_the_plugins_model_imports_no_gui_toolkit():
    """The plugin's model and results (``napari._model``, ``napari._results``) are plain
    Python: they run and are tested without Qt or napari."""
    pytest.importorskip("psygnal")
    code = SCRIPT.format(names=["napari_pfsdm.napari._model", "napari_pfsdm.napari._results",
                                "napari_pfsdm.napari._study_model"],
                         forbidden=set(FORBIDDEN), examples=str(EXAMPLES))
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         timeout=300, env={"PATH": "/usr/bin:/bin", "QT_API": "pyqt6"})
    assert out.returncode == 0, out.stderr
    result = json.loads(out.stdout.strip().splitlines()[-1])
    assert result["bad"] == [], f"GUI modules imported by the model: {result['bad'][:10]}"
