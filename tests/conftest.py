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
