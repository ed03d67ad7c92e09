"""The core never imports a plugin; the public API is curated."""

from __future__ import annotations

import ast
from pathlib import Path

import hapticframe
import hapticframe.kinds
import hapticframe.testing

CORE = Path(hapticframe.__file__).parent
PLUGINS = CORE.parent / "plugins"


def _imported_names(path: Path) -> set[str]:
    tree = ast.parse(path.read_text(encoding="utf-8"))
    names = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            names.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            names.add(node.module)
    return names


def test_core_never_imports_a_plugin_package():
    plugin_packages = {p.name for p in PLUGINS.iterdir() if p.is_dir()} | {"hapticframe_"}
    offenders = []
    for path in CORE.rglob("*.py"):
        for name in _imported_names(path):
            top = name.split(".")[0]
            if top in plugin_packages or top.startswith("hapticframe_"):
                offenders.append(f"{path.relative_to(CORE.parent)} imports {name}")
    assert not offenders, offenders


def test_bundled_plugins_use_only_the_public_api():
    offenders = []
    for path in PLUGINS.rglob("*.py"):
        for name in _imported_names(path):
            parts = name.split(".")
            if parts[0] == "hapticframe" and any(p.startswith("_") for p in parts[1:]):
                offenders.append(f"{path.relative_to(PLUGINS)} imports private {name}")
    assert not offenders, offenders


def test_public_names_are_sorted_and_exist():
    for module in (hapticframe, hapticframe.kinds, hapticframe.testing):
        names = module.__all__
        assert list(names) == sorted(names), f"{module.__name__}.__all__ is not sorted"
        assert len(set(names)) == len(names)
        for name in names:
            assert hasattr(module, name), f"{module.__name__}.{name}"
