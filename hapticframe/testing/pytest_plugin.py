"""An opt-in pytest plugin for plugin authors (not auto-loaded).

Enable it in a ``conftest.py``::

    pytest_plugins = ["hapticframe.testing.pytest_plugin"]

It adds a ``--hardware`` option and a ``hardware`` marker (tests marked with it are skipped
unless ``--hardware`` is given), and fixtures for building components the way the kit does.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from typing import Any

import pytest

from hapticframe._manager import make_plugin_manager
from hapticframe._registry import Registry
from hapticframe.testing._harness import DEFAULT_SCENE, make_component


def pytest_addoption(parser: pytest.Parser) -> None:
    parser.addoption(
        "--hardware", action="store_true", default=False,
        help="run tests marked 'hardware' (they need real devices)",
    )


def pytest_configure(config: pytest.Config) -> None:
    config.addinivalue_line("markers", "hardware: needs a real device; runs only with --hardware")


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    if config.getoption("--hardware"):
        return
    skip = pytest.mark.skip(reason="needs a real device: pass --hardware")
    for item in items:
        if "hardware" in item.keywords:
            item.add_marker(skip)


@pytest.fixture
def hapticframe_registry() -> Registry:
    """A fresh registry of the installed plugins (not the process-wide cached one)."""
    return make_plugin_manager().registry


@pytest.fixture
def build_component(hapticframe_registry: Registry) -> Iterator[Callable[..., Any]]:
    """``build_component(kind, name, **overrides)`` builds a plugin as the kit does."""
    from hapticframe._kind import Kind

    built: list[Any] = []

    def build(kind: str, name: str, *, seed: int = 0, config: dict[str, Any] | None = None) -> Any:
        spec = hapticframe_registry.get(Kind(kind), name).spec
        component = make_component(spec, registry=hapticframe_registry, seed=seed, config=config)
        built.append(component)
        return component

    yield build
    for component in built:
        component.close()


@pytest.fixture
def default_scene() -> Any:
    """The kit's scene: the thesis's 75 × 50 cm region with one 8 cm circle."""
    return DEFAULT_SCENE
