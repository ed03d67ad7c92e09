"""No plugin overrides a protected method of a class defined in another plugin (issue 32 §3).

A plugin that needs another plugin's behaviour changed uses its public seams (for a world:
:class:`hapticframe.kinds.World` and ``SandboxRobot.build_world``); overriding a
single-underscore method of another plugin's class ties the two to each other's internals.
Every module of every plugin package under ``plugins/`` is imported and every class it
defines is checked: for each protected method it defines, the nearest class up its MRO that
also defines the name must come from the same plugin package or from the core (whose
template methods, ``Robot._begin`` and the like, are meant to be overridden).
"""

from __future__ import annotations

import importlib
import inspect
import pkgutil
import sys
import types
from pathlib import Path

import pytest

import hapticframe

PLUGINS = Path(hapticframe.__file__).parent.parent / "plugins"


def plugin_packages(root: Path = PLUGINS) -> list[str]:
    """The plugin import packages under ``root`` (one folder each)."""
    return sorted(p.name for p in root.iterdir() if (p / "__init__.py").is_file())


def _is_method(value: object) -> bool:
    return inspect.isfunction(value) or isinstance(value, (staticmethod, classmethod, property))


def _protected(name: str) -> bool:
    return name.startswith("_") and not name.startswith("__")


def protected_overrides(classes: list[type], packages: set[str]) -> list[str]:
    """``'module.Class._name overrides other_package...Base._name'`` for each offence.

    ``packages`` are the plugin packages: a base from any other one than the class's own
    is another plugin's; a base from the core or elsewhere is not checked.
    """
    found = []
    for cls in classes:
        own = cls.__module__.split(".")[0]
        for name, value in vars(cls).items():
            if not (_protected(name) and _is_method(value)):
                continue
            base = next((b for b in cls.__mro__[1:] if name in vars(b)), None)
            if base is None:
                continue
            origin = base.__module__.split(".")[0]
            if origin in packages and origin != own:
                found.append(f"{cls.__module__}.{cls.__qualname__}.{name} overrides "
                             f"{base.__module__}.{base.__qualname__}.{name}")
    return sorted(found)


def _classes_of(module: types.ModuleType) -> list[type]:
    return [v for v in vars(module).values()
            if isinstance(v, type) and v.__module__ == module.__name__]


def plugin_classes(packages: list[str]) -> tuple[list[type], list[str]]:
    """Every class defined in the packages' modules, and the modules skipped because a
    third-party dependency (an optional extra) is not installed."""
    classes: list[type] = []
    skipped: list[str] = []
    ours = {*packages, "hapticframe"}
    for package in packages:
        root = importlib.import_module(package)
        names = [package] + [info.name for info in
                             pkgutil.walk_packages(root.__path__, package + ".")]
        for name in names:
            try:
                module = importlib.import_module(name)
            except ModuleNotFoundError as error:
                if (error.name or "").split(".")[0] in ours:
                    raise
                skipped.append(f"{name} (needs {error.name})")
                continue
            classes.extend(_classes_of(module))
    return classes, skipped


def test_no_plugin_overrides_another_plugins_protected_methods() -> None:
    packages = plugin_packages()
    classes, skipped = plugin_classes(packages)
    assert len(classes) > 50, "the walk found too few plugin classes to be a check"
    assert len(skipped) < len(classes)
    offenders = protected_overrides(classes, set(packages))
    assert not offenders, (
        "plugins override another plugin's protected methods (use a public seam instead):\n"
        + "\n".join(offenders)
    )


def _synthetic_plugins(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    """Two tiny plugin packages: ``seam_base`` and ``seam_user``, which subclasses it."""
    (tmp_path / "seam_base").mkdir()
    (tmp_path / "seam_base" / "__init__.py").write_text(
        "from seam_base._world import Engine\n")
    (tmp_path / "seam_base" / "_world.py").write_text(
        "class Engine:\n"
        "    def respond(self):\n        return self._force()\n"
        "    def _force(self):\n        return 1.0\n"
        "    def _helper(self):\n        return 0.0\n")
    (tmp_path / "seam_user").mkdir()
    (tmp_path / "seam_user" / "__init__.py").write_text("")
    (tmp_path / "seam_user" / "engines.py").write_text(
        "from seam_base import Engine\n"
        "class Public(Engine):\n"           # public override only: fine
        "    def respond(self):\n        return 2.0\n"
        "    def _own(self):\n        return 3.0\n"  # a protected method of its own: fine
        "class Offender(Engine):\n"
        "    def _force(self):\n        return 4.0\n"
        "class Indirect(Public):\n"          # nearest definition is seam_base's
        "    @property\n    def _helper(self):\n        return 5.0\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    for name in [m for m in sys.modules if m.split(".")[0] in ("seam_base", "seam_user")]:
        monkeypatch.delitem(sys.modules, name)
    return tmp_path


def test_a_synthetic_offender_is_named(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    root = _synthetic_plugins(tmp_path, monkeypatch)
    packages = plugin_packages(root)
    assert packages == ["seam_base", "seam_user"]
    classes, skipped = plugin_classes(packages)
    assert {c.__name__ for c in classes} == {"Engine", "Public", "Offender", "Indirect"}
    assert skipped == []
    assert protected_overrides(classes, set(packages)) == [
        "seam_user.engines.Indirect._helper overrides seam_base._world.Engine._helper",
        "seam_user.engines.Offender._force overrides seam_base._world.Engine._force",
    ]
    # Within one package, or against a base that is not a plugin's, nothing is reported.
    assert protected_overrides(classes, {"seam_user"}) == []


def test_a_missing_optional_dependency_skips_the_module(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    root = _synthetic_plugins(tmp_path, monkeypatch)
    (root / "seam_user" / "gpu.py").write_text("import not_installed_engine_xyz\n")
    classes, skipped = plugin_classes(plugin_packages(root))
    assert skipped == ["seam_user.gpu (needs not_installed_engine_xyz)"]
    assert len(classes) == 4
