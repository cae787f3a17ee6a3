"""Shared pytest configuration: the ``slow`` marker and the example world files."""

from __future__ import annotations

import functools
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
WORLD_DIRS = (ROOT / "navigation" / "data" / "worlds", ROOT / "worlds", Path("/work/shared/worlds"))


def pytest_configure(config):
    config.addinivalue_line("markers", "slow: long-running test (deselected by default; run with -m slow)")


def world_file(name: str) -> Path:
    """Path of an example world (``simple``, ``office``, ``cluttered20``)."""
    for d in WORLD_DIRS:
        p = d / f"{name}.json"
        if p.is_file():
            return p
    pytest.skip(f"example world {name}.json not found in {[str(d) for d in WORLD_DIRS]}")


@functools.lru_cache(maxsize=None)
def shared_world(name: str):
    """The example world ``name``, loaded once per test session."""
    import navigation

    return navigation.load_world(world_file(name))


@functools.lru_cache(maxsize=None)
def random_world(seed: int):
    """``tests.worldgen.random_forest_world(seed)``, generated once per test session."""
    from .worldgen import random_forest_world

    return random_forest_world(seed)
