"""The registry: every spec the loaded plugins yield, with where it came from."""

from __future__ import annotations

import difflib
import hashlib
import importlib.util
from collections.abc import Iterator
from dataclasses import dataclass, field

from hapticframe._errors import PluginConflictError, PluginError
from hapticframe._kind import Kind
from hapticframe._specs import BenchSpec, PluginSpec

__all__ = ["BrokenPlugin", "Conflict", "Registered", "Registry", "Source"]


@dataclass(frozen=True)
class Source:
    """Where a plugin comes from: its distribution and the entry point or module."""

    distribution: str
    version: str
    entry_point: str
    module: str = ""

    def __str__(self) -> str:
        return f"{self.distribution} {self.version} ({self.entry_point})"


@dataclass(frozen=True)
class Registered:
    """A spec and its source."""

    spec: PluginSpec
    source: Source

    @property
    def missing_requirements(self) -> tuple[str, ...]:
        """Modules in ``spec.requires`` that cannot be found (checked without importing)."""
        missing = []
        for module in self.spec.requires:
            try:
                found = importlib.util.find_spec(module) is not None
            except (ImportError, ValueError):
                found = False
            if not found:
                missing.append(module)
        return tuple(missing)


@dataclass(frozen=True)
class BrokenPlugin:
    """An entry point or plugin module that failed to load or register."""

    name: str
    source: Source
    error: str


#: The ``kind`` of a :class:`Conflict` between benchmark suites.
BENCHMARK = "benchmark"


@dataclass(frozen=True)
class Conflict:
    """One (kind, name) registered by more than one source (``kind`` is :data:`BENCHMARK`
    for two benchmark suites of one name)."""

    kind: Kind | str
    name: str
    sources: tuple[Source, ...]

    def message(self) -> str:
        who = "; ".join(str(s) for s in self.sources)
        return f"{self.kind} plugin {self.name!r} is registered more than once, by: {who}"


@dataclass
class Registry:
    """Specs by kind and name, benchmark suites, broken plugins and conflicts."""

    plugins: dict[Kind, dict[str, Registered]] = field(
        default_factory=lambda: {kind: {} for kind in Kind}
    )
    benchmarks: dict[str, tuple[BenchSpec, Source]] = field(default_factory=dict)
    broken: list[BrokenPlugin] = field(default_factory=list)
    conflicts: list[Conflict] = field(default_factory=list)
    #: Entry points that ``HAPTICFRAME_BLOCKED_PLUGINS`` kept from loading.
    blocked: list[Source] = field(default_factory=list)

    def add(self, spec: PluginSpec, source: Source) -> None:
        existing = self.plugins[spec.kind].get(spec.name)
        if existing is not None:
            self._conflict(spec.kind, spec.name, existing.source, source)
            return
        self.plugins[spec.kind][spec.name] = Registered(spec, source)

    def add_benchmark(self, spec: BenchSpec, source: Source) -> None:
        """Register a benchmark suite; a second suite of the same name is a conflict."""
        existing = self.benchmarks.get(spec.name)
        if existing is not None:
            self._conflict(BENCHMARK, spec.name, existing[1], source)
            return
        self.benchmarks[spec.name] = (spec, source)

    def _conflict(self, kind: Kind | str, name: str, first: Source, source: Source) -> None:
        for conflict in self.conflicts:
            if (conflict.kind, conflict.name) == (kind, name):
                self.conflicts.remove(conflict)
                sources = (*conflict.sources, source)
                break
        else:
            sources = (first, source)
        self.conflicts.append(Conflict(kind, name, sources))

    def raise_for_conflicts(self) -> None:
        if self.conflicts:
            raise PluginConflictError("\n".join(c.message() for c in self.conflicts))

    def __iter__(self) -> Iterator[Registered]:
        for kind in Kind:
            for name in sorted(self.plugins[kind]):
                yield self.plugins[kind][name]

    def names(self, kind: Kind) -> list[str]:
        return sorted(self.plugins[kind])

    def get(self, kind: Kind, name: str) -> Registered:
        """The registered plugin, or a :class:`PluginError` that says what to do instead."""
        try:
            return self.plugins[kind][name]
        except KeyError:
            raise PluginError(self.unknown_message(kind, name)) from None

    def find(self, name: str) -> list[Registered]:
        """Every plugin called ``name``, of any kind."""
        return [kinds[name] for kinds in self.plugins.values() if name in kinds]

    def _blocking(self, name: str) -> list[Source]:
        """The blocked entry points whose name, or whose module's, matches the type ``name``
        (``jamming`` for ``force-rate-jamming``, ``loadcell`` for ``lab-load-cell``): a
        blocked plugin is never imported, so its types are known only by its names."""
        def bare(text: str) -> str:
            return "".join(ch for ch in text.lower() if ch.isalnum())

        wanted = bare(name)
        found = []
        for source in self.blocked:
            module = source.module.partition(":")[0].split(".")[0]
            names = {bare(source.entry_point), bare(module.removeprefix("hapticframe_"))}
            if any(len(n) >= 3 and (n in wanted or (len(wanted) >= 3 and wanted in n))
                   for n in names):
                found.append(source)
        return found

    def unknown_message(self, kind: Kind, name: str) -> str:
        """Why ``name`` is not a usable plugin of ``kind`` and what is close to it."""
        from hapticframe._errors import shown

        blocking = self._blocking(name)
        if blocking:
            which = ", ".join(
                f"{s.entry_point!r} of {s.distribution} {s.version}" for s in blocking
            )
            parts = [
                f"{kind} type {shown(name)} is blocked: its plugin's entry point {which} is "
                "named in HAPTICFRAME_BLOCKED_PLUGINS, so it was not loaded; remove it from "
                "that variable to use the plugin"
            ]
        else:
            parts = [f"unknown {kind} type {shown(name)}"]
            if self.blocked:
                parts.append(
                    "not loaded because HAPTICFRAME_BLOCKED_PLUGINS names them: "
                    + ", ".join(f"{s.entry_point!r} of {s.distribution}" for s in self.blocked)
                    + " (it may be one of theirs)"
                )
        for broken in self.broken:
            if broken.name == name:
                parts.append(
                    f"a plugin of that name from {broken.source} failed to load: {broken.error}"
                )
        other_kinds = [str(r.spec.kind) for r in self.find(name)]
        if other_kinds:
            parts.append(
                f"{shown(name)} is a {', '.join(other_kinds)} plugin, not a {kind} plugin"
            )
        # A name far longer than any plugin's matches none (and difflib is quadratic).
        close = ([] if len(name) > 100
                 else difflib.get_close_matches(name, self.names(kind), n=3, cutoff=0.5))
        if close:
            parts.append("did you mean " + " or ".join(repr(c) for c in close))
        installed = self.names(kind)
        parts.append(
            f"installed {kind} plugins: {', '.join(installed)}" if installed
            else f"no {kind} plugins are installed"
        )
        return "; ".join(parts)

    def fingerprint(self) -> str:
        """A digest of the registered specs, for caching models built from them."""
        h = hashlib.sha256()
        for reg in self:
            h.update(f"{reg.spec.kind}:{reg.spec.name}:{reg.spec.config.__module__}."
                     f"{reg.spec.config.__qualname__}:{id(reg.spec.config)}\n".encode())
        return h.hexdigest()
