"""``hapticframe bench NAME``: run a benchmark suite registered by a plugin."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from hapticframe._errors import PluginConflictError, UsageError
from hapticframe._manager import get_registry
from hapticframe._registry import BENCHMARK
from hapticframe._specs import resolve_reference

__all__ = ["BenchOptions", "list_benches", "run_bench"]


@dataclass(frozen=True)
class BenchOptions:
    """What ``hapticframe bench`` passes to a suite.

    Parameters
    ----------
    out_dir : Path
        Where the suite writes its report (``<name>.md``, ``<name>.json``, figures).
    trials : int or None
        Trials per case; None lets the suite choose its default.
    seed : int
        Seeds every trial.
    quick : bool
        Run a reduced version (minutes, not hours).
    workers : int or None
        Processes a suite may use for independent trials (None: one per CPU).
    device : str
        Where a suite that trains models may train them, as a torch device name (``"cpu"``,
        ``"cuda"``, ``"cuda:1"``); suites that train nothing ignore it, and each suite
        checks the name itself.
    echo : callable
        Prints a progress line.
    overrides : tuple of str
        ``--set PATH=VALUE`` texts a suite that runs experiments applies to each of them
        (:func:`hapticframe.apply_overrides`); suites that run none ignore them.
    """

    out_dir: Path
    trials: int | None = None
    seed: int = 0
    quick: bool = False
    workers: int | None = None
    device: str = "cpu"
    echo: Callable[[str], None] = field(default=print)
    overrides: tuple[str, ...] = ()


def list_benches() -> list[str]:
    """One line per registered suite: its name and its summary (none installed: one line)."""
    registry = get_registry()
    if not registry.benchmarks:
        return ["no benchmark suites installed"]
    width = max(len(name) for name in registry.benchmarks)
    return [f"{name:<{width}}  {registry.benchmarks[name][0].summary}"
            for name in sorted(registry.benchmarks)]


def run_bench(name: str, options: BenchOptions) -> Any:
    """Look up the suite ``name`` and run it."""
    registry = get_registry()
    if name not in registry.benchmarks:
        available = ", ".join(sorted(registry.benchmarks)) or "none installed"
        raise UsageError(f"unknown benchmark {name!r}; available: {available}")
    for conflict in registry.conflicts:
        if (conflict.kind, conflict.name) == (BENCHMARK, name):
            raise PluginConflictError(conflict.message())
    spec, _source = registry.benchmarks[name]
    suite = resolve_reference(
        spec.factory, what=f"benchmark {name!r}", install_hint=spec.install_hint
    )
    options.out_dir.mkdir(parents=True, exist_ok=True)
    return suite(options)
