"""``hapticframe bench NAME``: run a benchmark suite registered by a plugin."""

from __future__ import annotations

import argparse
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from hapticframe._errors import PluginConflictError, UsageError
from hapticframe._manager import get_registry
from hapticframe._registry import BENCHMARK
from hapticframe._specs import resolve_reference
from hapticframe.cli._common import add_set_option, out, positive_int

__all__ = ["BenchOptions", "list_benches", "register", "run_bench"]


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
    data : Path or None
        ``--data DIR``: recordings a suite that reads real data reads (e.g. the Penn BOLT
        BioTac files for ``perception-real``); suites that read none ignore it.
    """

    out_dir: Path
    trials: int | None = None
    seed: int = 0
    quick: bool = False
    workers: int | None = None
    device: str = "cpu"
    echo: Callable[[str], None] = field(default=print)
    overrides: tuple[str, ...] = ()
    data: Path | None = None


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


def register(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Add ``hapticframe bench`` to the command line."""
    p = sub.add_parser("bench", help="run a benchmark suite (see `hapticframe plugins`)")
    p.add_argument("name", metavar="NAME", nargs="?", help="the suite to run; none: list them")
    p.add_argument("--trials", type=positive_int, default=None, help="trials per case")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--out", default="bench-out", metavar="DIR")
    p.add_argument("--quick", action="store_true", help="a reduced run")
    p.add_argument("--workers", type=positive_int, default=None,
                   help="processes for independent trials (default: one per CPU)")
    p.add_argument("--device", default="cpu",
                   help="where a suite that trains models trains them: cpu (default) or a "
                   "torch accelerator such as cuda")
    p.add_argument("--data", default=None, metavar="DIR",
                   help="recordings a suite reads (perception-real, biotac-calibration: the "
                   "Penn BOLT .h5 files)")
    add_set_option(p, "every experiment the suite runs (suites that run experiment "
                    "files: search)")
    p.set_defaults(func=cmd_bench)


def cmd_bench(args: argparse.Namespace) -> int:
    if args.name is None:
        for line in list_benches():
            out(line)
        return 0
    options = BenchOptions(
        out_dir=Path(args.out), trials=args.trials, seed=args.seed, quick=args.quick,
        workers=args.workers, device=args.device, echo=out,
        overrides=tuple(o.text for o in args.set),
        data=None if args.data is None else Path(args.data),
    )
    run_bench(args.name, options)
    return 0

