"""``hapticframe sweep``: vary settings over seeded trials: accuracy against cost, ."""

from __future__ import annotations

import argparse
import math
from pathlib import Path
from typing import Any

from hapticframe.cli._common import (
    add_plugin_module_option,
    add_set_option,
    out,
    positive_int,
    progress_line,
)

__all__ = ["register"]


def register(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Add ``hapticframe sweep`` to the command line."""
    p = sub.add_parser("sweep", help="vary settings over seeded trials: accuracy against cost, "
                       "the Pareto front")
    p.add_argument("file", metavar="EXPERIMENT")
    p.add_argument("--vary", action="append", type=_vary, default=[], metavar="PATH=V1,V2,...",
                   help="a knob and its values (each YAML), e.g. bhm.hinge_spacing_m=0.025,0.05;"
                   " repeatable")
    p.add_argument("--declared", action="store_true",
                   help="also vary every knob the experiment's plugins declare")
    p.add_argument("--grid", action="store_true",
                   help="every combination of the values (default: one knob at a time from "
                   "the file's values, plus the file itself)")
    p.add_argument("--trials", type=positive_int, default=3,
                   help="seeded trials per point: seed, seed + 1, ... (default 3)")
    p.add_argument("--out", required=True, metavar="DIR",
                   help="directory for sweep.json, sweep.md, pareto.png and the runs")
    p.add_argument("--overwrite", action="store_true",
                   help="clear an earlier sweep in --out first (only the files its "
                   "sweep.json lists)")
    p.add_argument("--workers", type=positive_int, default=None,
                   help="worker processes (default: one per CPU)")
    p.add_argument("--timeout-s", type=_seconds, default=None, metavar="T",
                   help="a trial running longer is a 'timeout' row (default: no limit)")
    p.add_argument("--executor", choices=("process", "dask"), default="process",
                   help="process: a local process pool (default); dask: a Dask cluster "
                   "(--scheduler, else a LocalCluster; needs hapticframe[distributed])")
    p.add_argument("--scheduler", default=None, metavar="ADDRESS",
                   help="the Dask scheduler, e.g. tcp://head-node:8786 (--executor dask)")
    add_set_option(p, "every point")
    add_plugin_module_option(p)
    p.set_defaults(func=cmd_sweep)


def _vary(text: str) -> Any:
    """A ``--vary PATH=V1,V2,...`` (see :mod:`hapticframe.sweep._sweep`), parsed when read."""
    from hapticframe._errors import UsageError
    from hapticframe.sweep._sweep import parse_vary

    try:
        return parse_vary(text)
    except UsageError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


def _seconds(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number of seconds") from None
    if not math.isfinite(value) or value <= 0:
        raise argparse.ArgumentTypeError("must be a finite number of seconds above 0")
    return value


def cmd_sweep(args: argparse.Namespace) -> int:
    from hapticframe.sweep._sweep import SweepOptions, run_sweep

    options = SweepOptions(
        varies=tuple(args.vary), declared=args.declared, grid=args.grid, trials=args.trials,
        workers=args.workers, timeout_s=args.timeout_s, executor=args.executor,
        scheduler=args.scheduler, overrides=tuple(args.set),
        plugin_modules=tuple(args.plugin_module or ()), echo=progress_line,
        overwrite=args.overwrite,
    )
    result = run_sweep(args.file, args.out, options)
    failed = [p for p in result["points"] if p["status"] != "ok"]
    front = ", ".join(result["front"]) or "none"
    out(f"{len(result['points'])} points, {len(failed)} failed or refused; Pareto front: "
         f"{front}; table in {Path(args.out) / 'sweep.md'}")
    return 0

