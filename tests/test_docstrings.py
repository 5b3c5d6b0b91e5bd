"""Every example in the docstrings of the headless package runs and prints what it says (the
plugin's, under napari/, need Qt and are left to its own tests)."""

from __future__ import annotations

import doctest
import importlib
from pathlib import Path

import pytest

SRC = Path(__file__).resolve().parents[1] / "src" / "napari_pfsdm"
MODULES = sorted(
    "napari_pfsdm." + ".".join(p.relative_to(SRC).with_suffix("").parts).removesuffix(
        ".__init__")
    for p in SRC.rglob("*.py")
    if "napari" not in p.relative_to(SRC).parts[:1] and p.name != "__main__.py")


@pytest.mark.parametrize("name", MODULES)
def test_docstring_examples_run(name):
    module = importlib.import_module(name)
    flags = doctest.NORMALIZE_WHITESPACE | doctest.ELLIPSIS
    result = doctest.testmod(module, optionflags=flags, verbose=False, report=False)
    assert result.failed == 0, f"{result.failed} docstring example(s) of {name} fail"
