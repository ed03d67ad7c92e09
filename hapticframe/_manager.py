"""The pluggy plugin manager: entry-point discovery, blocking and provenance.

The manager is built on first use (:func:`get_plugin_manager`, cached), never at import.
Environment controls:

``HAPTICFRAME_DISABLE_PLUGIN_AUTOLOAD``
    Set to ``1`` to load only the plugins bundled with hapticframe itself (entry points of
    other distributions are skipped), as pytest does for ``pytest11``.
``HAPTICFRAME_BLOCKED_PLUGINS``
    Comma-separated entry-point names that are not loaded (bundled ones included).
"""

from __future__ import annotations

import functools
import importlib
import importlib.metadata as metadata
import os
import sys
import types
import warnings
from collections.abc import Iterable, Sequence
from pathlib import Path
from typing import Any

import pluggy

from hapticframe import hookspecs
from hapticframe._errors import PluginImportError
from hapticframe._kind import Kind
from hapticframe._registry import BrokenPlugin, Registry, Source
from hapticframe._specs import SPEC_TYPES, BenchSpec, add_local_module_dir

__all__ = [
    "AUTOLOAD_ENV",
    "BLOCKED_ENV",
    "ENTRY_POINT_GROUP",
    "PluginManager",
    "get_plugin_manager",
    "get_registry",
    "make_plugin_manager",
]

ENTRY_POINT_GROUP = "hapticframe"
AUTOLOAD_ENV = "HAPTICFRAME_DISABLE_PLUGIN_AUTOLOAD"
BLOCKED_ENV = "HAPTICFRAME_BLOCKED_PLUGINS"
_CORE_DISTRIBUTION = "hapticframe"


class PluginLoadWarning(UserWarning):
    """A plugin failed to load and was skipped."""


class PluginManager(pluggy.PluginManager):
    """A pluggy manager that remembers where each plugin came from."""

    def __init__(self) -> None:
        super().__init__(hookspecs.PROJECT_NAME)
        self.add_hookspecs(hookspecs)
        self.sources: dict[int, Source] = {}
        self.broken: list[BrokenPlugin] = []
        #: Entry points not loaded because HAPTICFRAME_BLOCKED_PLUGINS (or ``blocked``)
        #: names them: a type they register is reported as blocked, not as unknown.
        self.blocked: list[Source] = []
        self._registry: Registry | None = None

    def parse_hookimpl_opts(self, plugin: Any, name: str) -> Any:
        # Only look at hapticframe_* attributes, so arbitrary module attributes are ignored.
        if not name.startswith("hapticframe_"):
            return None
        return super().parse_hookimpl_opts(plugin, name)

    def register_source(self, plugin: object, source: Source) -> None:
        """Register ``plugin`` and remember its source; a failure marks it broken."""
        try:
            self.register(plugin, name=f"{source.distribution}:{source.entry_point}")
        except Exception as exc:  # a malformed plugin must not stop the others
            self.mark_broken(source.entry_point, source, exc)
            return
        self.sources[id(plugin)] = source
        self._registry = None

    def mark_broken(self, name: str, source: Source, exc: BaseException) -> None:
        error = f"{type(exc).__name__}: {exc}"
        self.broken.append(BrokenPlugin(name, source, error))
        warnings.warn(
            f"hapticframe plugin {name!r} from {source} was skipped: {error}",
            PluginLoadWarning,
            stacklevel=3,
        )

    @property
    def registry(self) -> Registry:
        """All specs yielded by the registered plugins (built once, then cached)."""
        if self._registry is None:
            self._registry = self._collect()
        return self._registry

    def _collect(self) -> Registry:
        registry = Registry(broken=list(self.broken), blocked=list(self.blocked))
        for kind in Kind:
            caller = getattr(self.hook, kind.hook_name)
            for impl in caller.get_hookimpls():
                source = self._source_of(impl.plugin)
                for record in self._records(impl, source, registry):
                    if not isinstance(record, SPEC_TYPES[kind]):
                        registry.broken.append(BrokenPlugin(
                            impl.plugin_name, source,
                            f"{kind.hook_name} yielded {type(record).__name__}, "
                            f"expected {SPEC_TYPES[kind].__name__}",
                        ))
                        continue
                    registry.add(record, source)
        for impl in self.hook.hapticframe_benchmarks.get_hookimpls():
            source = self._source_of(impl.plugin)
            for record in self._records(impl, source, registry):
                if not isinstance(record, BenchSpec):
                    registry.broken.append(BrokenPlugin(
                        impl.plugin_name, source,
                        f"hapticframe_benchmarks yielded {type(record).__name__}, "
                        "expected BenchSpec",
                    ))
                    continue
                registry.add_benchmark(record, source)
        return registry

    def _source_of(self, plugin: object) -> Source:
        return self.sources.get(id(plugin), Source("<unknown>", "", str(plugin)))

    @staticmethod
    def _records(impl: Any, source: Source, registry: Registry) -> list[Any]:
        try:
            result = impl.function()
            return list(result) if result is not None else []
        except Exception as exc:
            registry.broken.append(
                BrokenPlugin(impl.plugin_name, source, f"{type(exc).__name__}: {exc}")
            )
            return []


def _blocked_from_env() -> set[str]:
    raw = os.environ.get(BLOCKED_ENV, "")
    return {name.strip() for name in raw.split(",") if name.strip()}


def _autoload_disabled() -> bool:
    return os.environ.get(AUTOLOAD_ENV, "").strip().lower() not in ("", "0", "false", "no")


def _entry_points() -> Iterable[tuple[metadata.EntryPoint, str, str]]:
    seen = set()
    for dist in metadata.distributions():
        dist_name = dist.metadata["Name"] or "<unnamed>"
        for ep in dist.entry_points:
            if ep.group != ENTRY_POINT_GROUP:
                continue
            key = (dist_name.lower(), ep.name, ep.value)
            if key in seen:  # the same distribution found twice on sys.path
                continue
            seen.add(key)
            yield ep, dist_name, dist.version


def make_plugin_manager(
    *,
    autoload: bool | None = None,
    blocked: Iterable[str] | None = None,
    strict: bool = False,
    modules: Sequence[str] = (),
    module_dir: Path | None = None,
) -> PluginManager:
    """Build a fresh plugin manager.

    Parameters
    ----------
    autoload : bool, optional
        Load entry points of distributions other than hapticframe. Default: on, unless
        ``HAPTICFRAME_DISABLE_PLUGIN_AUTOLOAD`` is set.
    blocked : iterable of str, optional
        Entry-point names not to load. Default: ``HAPTICFRAME_BLOCKED_PLUGINS``.
    strict : bool
        Raise :class:`PluginImportError` for the first plugin that fails to load instead
        of listing it as broken.
    modules : sequence of str
        Extra plugin modules to import and register (lab-local modules named by the person
        running a command, ``--plugin-module``; experiment files never name code).
    module_dir : Path, optional
        Directory searched first for ``modules`` (the experiment file's directory).
    """
    autoload = not _autoload_disabled() if autoload is None else autoload
    blocked_names = _blocked_from_env() if blocked is None else set(blocked)
    pm = PluginManager()
    for name in blocked_names:
        pm.set_blocked(name)
    for ep, dist_name, version in _entry_points():
        is_core = dist_name.lower() == _CORE_DISTRIBUTION
        source = Source(dist_name, version, ep.name, ep.value)
        if ep.name in blocked_names:
            pm.blocked.append(source)
            continue
        if not autoload and not is_core:
            continue
        try:
            plugin = ep.load()
        except Exception as exc:
            if strict:
                raise PluginImportError(
                    f"plugin {ep.name!r} from {source} failed to import: "
                    f"{type(exc).__name__}: {exc}"
                ) from exc
            pm.mark_broken(ep.name, source, exc)
            continue
        pm.register_source(plugin, source)
    for module_name in modules:
        _register_module(pm, module_name, module_dir)
    try:
        pm.check_pending()
    except pluggy.PluginValidationError as exc:
        plugin = exc.plugin
        source = pm.sources.get(id(plugin), Source("<unknown>", "", str(plugin)))
        if strict:
            raise PluginImportError(f"plugin from {source}: {exc}") from exc
        pm.unregister(plugin)
        pm.mark_broken(source.entry_point, source, exc)
    pm.hook.hapticframe_addhooks.call_historic(kwargs={"pluginmanager": pm})
    if strict and pm.broken:
        first = pm.broken[0]
        raise PluginImportError(f"plugin {first.name!r} from {first.source}: {first.error}")
    return pm


def _register_module(pm: PluginManager, module_name: str, module_dir: Path | None) -> None:
    """Import a lab-local plugin module (trusted code named on the command line)."""
    added = False
    if module_dir is not None and str(module_dir) not in sys.path:
        sys.path.insert(0, str(module_dir))
        added = True
    try:
        module: types.ModuleType = importlib.import_module(module_name)
    except Exception as exc:
        raise PluginImportError(
            f"plugin module {module_name!r} failed to import: {type(exc).__name__}: {exc}"
        ) from exc
    finally:
        if added:
            sys.path.remove(str(module_dir))
    if module_dir is not None:
        add_local_module_dir(str(module_dir))
    if pm.is_registered(module):
        return  # already loaded through its entry point: the same module, nothing to add
    pm.register_source(module, Source("<plugin-module>", "", module_name, module_name))


@functools.cache
def get_plugin_manager() -> PluginManager:
    """The process-wide plugin manager, built on first use from the environment."""
    return make_plugin_manager()


def get_registry() -> Registry:
    """The registry of the process-wide plugin manager."""
    return get_plugin_manager().registry
