"""What the subcommands share: output, options, validation and the experiment's summary."""

from __future__ import annotations

import argparse
import math
import os
import sys
from pathlib import Path
from typing import Any, TextIO

from hapticframe._defaults import LIVE_PORT

__all__ = [
    "LIVE_PORT",
    "SUMMARY_METRICS",
    "add_out_options",
    "add_plugin_module_option",
    "add_port_option",
    "add_set_option",
    "closed_pipe",
    "err",
    "megabytes_arg",
    "min_free",
    "out",
    "override_arg",
    "plugin_manager",
    "plugin_module_arg",
    "port_arg",
    "port_of",
    "positive_int",
    "print_warnings",
    "progress_line",
    "short_number",
    "summary_line",
    "validate_experiment",
    "wait_for_interrupt",
]


def out(text: str = "", stream: TextIO | None = None) -> None:
    print(text, file=stream or sys.stdout, flush=True)


def err(text: str) -> None:
    print(text, file=sys.stderr, flush=True)


def progress_line(text: str) -> None:
    """A progress line of a long command: once the reader of stdout has gone away (a
    closed pipe), the command carries on and writes its results without printing."""
    try:
        out(text)
    except BrokenPipeError:
        closed_pipe()


def plugin_module_arg(text: str) -> str:
    """A ``--plugin-module`` value: a dotted module name, never a path."""
    import re

    from hapticframe._config._model import MODULE_PATTERN

    if not re.fullmatch(MODULE_PATTERN, text):
        raise argparse.ArgumentTypeError(
            f"{text!r} is not a module name (letters, digits, _ and dots; no paths)")
    return text


def validate_experiment(args: argparse.Namespace, file: str, command: str = "run") -> Any:
    """Validate ``file`` for ``command`` (``run`` or ``train``) against the command's plugins
    (see :func:`plugin_manager`)."""
    from hapticframe._config import load_file
    from hapticframe._config._overrides import validate_with_overrides

    loaded = load_file(file)
    experiment = validate_with_overrides(
        loaded, getattr(args, "set", None) or (), strict=args.strict,
        plugin_manager=plugin_manager(args, args.strict), command=command)
    print_warnings(experiment)
    return experiment


def print_warnings(experiment: Any) -> None:
    """What is legal but suspicious, located like errors: ``warning: FILE:LINE: PATH: ...``
    on stderr (``validate``, ``run`` and ``train`` all print them)."""
    for issue in experiment.warnings:
        err(f"warning: {issue.render(experiment.file)}")


def override_arg(text: str) -> Any:
    """A ``--set PATH=VALUE`` (see :mod:`hapticframe._config._overrides`), parsed when read."""
    from hapticframe._config._overrides import parse_override
    from hapticframe._errors import UsageError

    try:
        return parse_override(text)
    except UsageError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


def add_set_option(p: argparse.ArgumentParser, what: str = "the experiment") -> None:
    p.add_argument(
        "--set", action="append", type=override_arg, default=[], metavar="PATH=VALUE",
        help=f"change one value of {what} before validation, as if the file said it "
        "(VALUE is YAML): maps[0].config.hinge_spacing_m=0.025, bhm.hinge_spacing_m=0.025 "
        "(a component's config field by its id), run.max_movements=10, seed=3; repeatable, "
        "recorded in run.json",
    )


def add_plugin_module_option(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--plugin-module", action="append", type=plugin_module_arg, metavar="NAME",
        help="import a lab-local plugin module first (trusted code, searched first in the "
        "current directory); repeatable. Experiment files never name code to import.",
    )


def plugin_manager(args: argparse.Namespace, strict: bool = False) -> Any:
    """The plugin manager of a command: the process-wide one, or a fresh one when the
    command is strict or names ``--plugin-module`` modules (searched first in the current
    directory)."""
    from hapticframe._errors import PluginImportError, UsageError
    from hapticframe._manager import get_plugin_manager, make_plugin_manager

    modules = getattr(args, "plugin_module", None) or ()
    if not modules:
        return make_plugin_manager(strict=True) if strict else get_plugin_manager()
    try:
        return make_plugin_manager(strict=strict, modules=list(modules), module_dir=Path.cwd())
    except PluginImportError as exc:
        raise UsageError(f"--plugin-module: {exc}") from exc


#: The figures the summary line of ``hapticframe run`` shows, when a run has them; every
#: metric stays in ``metrics.json``.
SUMMARY_METRICS = (
    "movements",
    "object_found",
    "objects_found",
    "objects_missed",
    "false_blobs",
    "centroid_error_m",
    "hausdorff_est_to_true_m",
    "hausdorff_true_to_est_m",
    "max_measured_force_n",
    "contact_balanced_accuracy",
    "first_contact_error_s",
    "last_contact_error_s",
    "wall_time_s",
)
#: Scores of a classifier that estimates where the object is (``<id>_distance_mae_mm``, ...,
#: as the raking estimator's finalize names them), printed before the wall time.
SUMMARY_SCORE_SUFFIXES = ("_distance_mae_mm", "_direction_accuracy", "_depth_accuracy")


def summary_line(metrics: Any, label_channel: str = "contact", *, searched: bool = True) -> str:
    """The few figures a person reads after a run: search result, force, accuracy, time
    (``contact`` in the names stands for ``run.label_channel``). ``searched``: False for a
    run without a planner (perception, raking), whose zero movements say nothing."""
    wanted = [k.replace("contact_", f"{label_channel}_", 1) for k in SUMMARY_METRICS]
    if not searched or ("object_found" not in metrics and "objects_found" not in metrics):
        wanted.remove("movements")  # no search: a perception run's zero movements say nothing
    scores = [k for k in metrics if isinstance(k, str) and k.endswith(SUMMARY_SCORE_SUFFIXES)]
    if scores:
        at = wanted.index("wall_time_s")
        wanted[at:at] = [k for k in scores if k not in wanted]
    parts = []
    for key in wanted:
        value = metrics.get(key)
        if isinstance(value, bool):
            parts.append(f"{key}={'yes' if value else 'no'}")
        elif isinstance(value, (int, float)) and not math.isnan(value):  # NaN: metrics.json
            parts.append(f"{key}={short_number(value)}")
    return ", ".join(parts)


def searches(experiment: Any) -> bool:
    """Whether ``experiment`` plans movements (has a planner): its summary counts them."""
    from hapticframe._kind import Kind

    return bool(experiment.of_kind(Kind.PLANNER))


def wait_for_interrupt() -> None:
    """Block until Ctrl-C (the live page keeps serving meanwhile)."""
    import threading

    forever = threading.Event()
    try:
        while not forever.wait(3600):
            pass
    except KeyboardInterrupt:
        pass


def min_free(args: argparse.Namespace) -> int | None:
    """``--min-free-mb`` in bytes; None: the default (HAPTICFRAME_MIN_FREE_MB or 50 MB)."""
    megabytes = getattr(args, "min_free_mb", None)
    return None if megabytes is None else int(megabytes * 1024 * 1024)


def megabytes_arg(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number of megabytes") from None
    if not math.isfinite(value) or value < 0:
        raise argparse.ArgumentTypeError("must be a finite number of megabytes, at least 0")
    return value


def add_out_options(p: argparse.ArgumentParser, what: str, replaces: str) -> None:
    p.add_argument("--out", required=True, metavar="DIR", help=f"directory for {what}")
    p.add_argument("--overwrite", action="store_true",
                   help=f"delete {replaces} already in DIR first (only files hapticframe "
                   "wrote and listed; refused when DIR holds others)")
    p.add_argument("--min-free-mb", type=megabytes_arg, default=None, metavar="MB",
                   help="free space DIR must have before anything runs (default: "
                   "HAPTICFRAME_MIN_FREE_MB or 50)")


def port_arg(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a port number") from None
    if not 0 <= value <= 65535:
        raise argparse.ArgumentTypeError("must be 0 (any free port) ... 65535")
    return value



def add_port_option(p: argparse.ArgumentParser) -> None:
    p.add_argument("--port", type=port_arg, default=None,
                   help=f"the live page's port on 127.0.0.1 (default {LIVE_PORT}; 0: any "
                   "free port; printed at start)")


def port_of(args: argparse.Namespace) -> int:
    port: int | None = getattr(args, "port", None)
    return LIVE_PORT if port is None else port


def short_number(value: float) -> str:
    return f"{value:.4g}" if isinstance(value, float) else str(value)


def positive_int(text: str) -> int:
    value = int(text)
    if value < 1:
        raise argparse.ArgumentTypeError("must be at least 1")
    return value


def closed_pipe() -> int:
    """The reader of our output went away (``| head``): stop quietly, as ``cat`` does.

    stdout is pointed at devnull so that the interpreter's final flush of the broken
    stream raises nothing more.
    """
    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        os.close(devnull)
    except (OSError, ValueError):  # stdout without a descriptor (a test's capture)
        pass
    return 0

