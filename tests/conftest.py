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


_GUI_MISSING = _gui_stack_missing()

#: Without the GUI stack, tests/gui is not entered at all (no errors at collection, not even its
#: conftest); the run's header says so.
collect_ignore = ["gui"] if _GUI_MISSING else []


def pytest_report_header(config):
    if _GUI_MISSING:
        return [f"tests/gui not collected: {_GUI_MISSING} (the non-GUI run, docs/testing.md)"]
    return []
