"""Shared fixtures."""

import numpy as np
import pytest

from shapes_fixture import BASE_SHAPES


@pytest.fixture
def base_shapes():
    return BASE_SHAPES


@pytest.fixture
def rng():
    return np.random.default_rng(1234)


def _gui_stack_missing() -> str:
    """Why the GUI tests cannot run here ("" when they can): napari and pytest-qt with a Qt
    binding. A core + testing install runs the other tests without them (docs/testing.md)."""
    import importlib.util

    for module in ("napari", "pytestqt", "qtpy"):
        if importlib.util.find_spec(module) is None:
            return f"{module} is not installed"
    return ""


#: Without the GUI stack, tests/gui is not collected at all (not errors at collection).
collect_ignore_glob = ["gui/*"] if _gui_stack_missing() else []
