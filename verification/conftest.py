"""Shared fixtures of the theorem-checking suite: exact tableaux are built once per session
(Gauss s = 4, 5 take ~10 s each in sympy)."""
import functools

import pytest

from ldaspark.models.scenes import get_scene
from ldaspark.core.families import get_method


@functools.lru_cache(maxsize=None)
def _exact_method(name):
    return get_method(name, exact=True)


@functools.lru_cache(maxsize=None)
def _scene(name):
    return get_scene(name)


@pytest.fixture(scope="session")
def exact_method():
    """exact_method(name) -> cached exact SparkTableau."""
    return _exact_method


@pytest.fixture(scope="session")
def scene():
    """scene(name) -> cached Scene."""
    return _scene


@pytest.fixture
def exhaustive(request):
    return request.config.getoption("--exhaustive")
