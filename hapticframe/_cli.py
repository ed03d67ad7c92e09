"""The ``hapticframe`` command line.

Kept import-light: each command imports what it needs when it runs, so ``--help``,
``plugins``, ``validate`` and ``schema`` never load torch, scikit-learn or device libraries.
Exit status: 0 success, 1 failure while running, 2 bad input or usage, 130 or 143 a run
interrupted by SIGINT (Ctrl-C) or SIGTERM. Output cut short by a closed pipe
(``hapticframe schema | head``) is not an error.

The library logs through :mod:`logging` and prints nothing itself; :func:`main` sends the
``hapticframe`` logger's warnings (and, for the duration of the command, Python warnings)
to stderr as one line each.
"""

from __future__ import annotations

import argparse
import logging
import math
import os
import sys
import warnings
from collections.abc import Sequence
from pathlib import Path
from typing import Any, TextIO

__all__ = ["main"]


def _out(text: str = "", stream: TextIO | None = None) -> None:
    print(text, file=stream or sys.stdout, flush=True)


def _err(text: str) -> None:
    print(text, file=sys.stderr, flush=True)


def _progress_line(text: str) -> None:
    """A progress line of a long command: once the reader of stdout has gone away (a
    closed pipe), the command carries on and writes its results without printing."""
    try:
        _out(text)
    except BrokenPipeError:
        _closed_pipe()


def _one_line_warning(message: Any, category: Any, filename: str, lineno: int, file: Any = None,
                      line: Any = None) -> None:
    _err(f"warning: {message}")


class _StderrHandler(logging.Handler):
    """The library's log records as ``warning: message`` lines on the current stderr."""

    def emit(self, record: logging.LogRecord) -> None:
        try:
            _err(f"{record.levelname.lower()}: {record.getMessage()}")
        except Exception:  # logging's own policy for a failing handler
            self.handleError(record)


def _configure_logging(debug: bool) -> logging.Handler:
    handler = _StderrHandler(logging.DEBUG if debug else logging.WARNING)
    logger = logging.getLogger("hapticframe")
    logger.addHandler(handler)
    if debug:
        logger.setLevel(logging.DEBUG)
    return handler


def _plugin_module(text: str) -> str:
    """A ``--plugin-module`` value: a dotted module name, never a path."""
    import re

    from ._config._model import MODULE_PATTERN

    if not re.fullmatch(MODULE_PATTERN, text):
        raise argparse.ArgumentTypeError(
            f"{text!r} is not a module name (letters, digits, _ and dots; no paths)")
    return text


def _validate(args: argparse.Namespace, file: str, command: str = "run") -> Any:
    """Validate ``file`` for ``command`` (``run`` or ``train``) against the command's plugins
    (see :func:`_manager`)."""
    from ._config import load_file
    from ._overrides import validate_with_overrides

    loaded = load_file(file)
    experiment = validate_with_overrides(
        loaded, getattr(args, "set", None) or (), strict=args.strict,
        plugin_manager=_manager(args, args.strict), command=command)
    _print_warnings(experiment)
    return experiment


def _print_warnings(experiment: Any) -> None:
    """What is legal but suspicious, located like errors: ``warning: FILE:LINE: PATH: ...``
    on stderr (``validate``, ``run`` and ``train`` all print them)."""
    for issue in experiment.warnings:
        _err(f"warning: {issue.render(experiment.file)}")


def _override(text: str) -> Any:
    """A ``--set PATH=VALUE`` (see :mod:`hapticframe._overrides`), parsed when read."""
    from ._errors import UsageError
    from ._overrides import parse_override

    try:
        return parse_override(text)
    except UsageError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


def _add_set_option(p: argparse.ArgumentParser, what: str = "the experiment") -> None:
    p.add_argument(
        "--set", action="append", type=_override, default=[], metavar="PATH=VALUE",
        help=f"change one value of {what} before validation, as if the file said it "
        "(VALUE is YAML): maps[0].config.hinge_spacing_m=0.025, bhm.hinge_spacing_m=0.025 "
        "(a component's config field by its id), run.max_movements=10, seed=3; repeatable, "
        "recorded in run.json",
    )


def _add_plugin_module_option(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--plugin-module", action="append", type=_plugin_module, metavar="NAME",
        help="import a lab-local plugin module first (trusted code, searched first in the "
        "current directory); repeatable. Experiment files never name code to import.",
    )


# --- commands --------------------------------------------------------------------------------


def _manager(args: argparse.Namespace, strict: bool = False) -> Any:
    """The plugin manager of a command: the process-wide one, or a fresh one when the
    command is strict or names ``--plugin-module`` modules (searched first in the current
    directory)."""
    from ._errors import PluginImportError, UsageError
    from ._manager import get_plugin_manager, make_plugin_manager

    modules = getattr(args, "plugin_module", None) or ()
    if not modules:
        return make_plugin_manager(strict=True) if strict else get_plugin_manager()
    try:
        return make_plugin_manager(strict=strict, modules=list(modules), module_dir=Path.cwd())
    except PluginImportError as exc:
        raise UsageError(f"--plugin-module: {exc}") from exc


def cmd_plugins(args: argparse.Namespace) -> int:
    pm = _manager(args, strict=args.strict)
    registry = pm.registry
    rows, regs = [], list(registry)
    for reg in regs:
        missing = reg.missing_requirements
        conflicted = any((c.kind, c.name) == reg.spec.key for c in registry.conflicts)
        status = "conflict" if conflicted else (
            f"needs {', '.join(missing)}" if missing else "ok"
        )
        rows.append((str(reg.spec.kind), reg.spec.name, reg.source.distribution,
                     reg.source.version, status, reg.spec.summary))
    if args.json:
        import json

        from ._knobs import RUN_KNOBS, knob_record

        data = {
            "plugins": [
                dict(zip(("kind", "name", "distribution", "version", "status", "summary"), r,
                         strict=True), knobs=[knob_record(k) for k in reg.spec.knobs])
                for r, reg in zip(rows, regs, strict=True)
            ],
            "run_knobs": [knob_record(k) for k in RUN_KNOBS],
            "benchmarks": sorted(registry.benchmarks),
            "broken": [{"name": b.name, "source": str(b.source), "error": b.error}
                       for b in registry.broken],
            "conflicts": [c.message() for c in registry.conflicts],
        }
        _out(json.dumps(data, indent=2))
        return 0
    if args.knobs:
        return _print_knobs(registry)
    header = ("KIND", "NAME", "DISTRIBUTION", "VERSION", "STATUS", "SUMMARY")
    widths = [max(len(str(r[i])) for r in [header, *rows]) for i in range(5)]
    for row in [header, *rows]:
        padded = "  ".join(str(c).ljust(w) for c, w in zip(row[:5], widths, strict=True))
        _out(padded + "  " + row[5])
    for broken in registry.broken:
        _out(f"broken   {broken.name}  from {broken.source}: {broken.error}")
    for conflict in registry.conflicts:
        _out(f"conflict {conflict.message()}")
    if registry.benchmarks:
        _out(f"benchmarks: {', '.join(sorted(registry.benchmarks))}")
    return 0


def _print_knobs(registry: Any) -> int:
    """``hapticframe plugins --knobs``: each plugin's declared knobs, then the run loop's."""
    from ._knobs import RUN_KNOBS, describe_values

    rows = [(f"{reg.spec.kind}/{reg.spec.name}", knob) for reg in registry
            for knob in reg.spec.knobs]
    rows += [("run", knob) for knob in RUN_KNOBS]
    header = ("PLUGIN", "FIELD", "VALUES", "TRADES")
    cells = [(owner, knob.field, describe_values(knob), knob.trades) for owner, knob in rows]
    widths = [max(len(r[i]) for r in [header, *cells]) for i in range(3)]
    for row in [header, *cells]:
        _out("  ".join(c.ljust(w) for c, w in zip(row[:3], widths, strict=True)) + "  " + row[3])
    without = sorted(f"{reg.spec.kind}/{reg.spec.name}" for reg in registry if not reg.spec.knobs)
    if without:
        _out(f"no knobs: {', '.join(without)}")
    return 0


def cmd_validate(args: argparse.Namespace) -> int:
    from ._errors import ExperimentError

    status = 0
    for file in args.files:
        try:
            experiment = _validate(args, file)
        except ExperimentError as exc:
            _err(exc.render())
            status = 2
            continue
        parts = ", ".join(f"{e.id} ({e.type})" for e in experiment.components)
        _out(f"{file}: ok — {len(experiment.components)} components: {parts or 'none'}")
    return status


def cmd_schema(args: argparse.Namespace) -> int:
    from ._manager import get_registry
    from ._schema import render_schemas, schema_diff, shipped, write_schemas

    registry = get_registry()
    if args.dir is None:
        # The repository's schemas/ describes the plugins hapticframe ships, whatever else
        # is installed; --dir DIR covers every installed plugin (a lab's own schemas).
        directory, dir_option = Path("schemas"), ""
        if args.check or args.write:
            registry = shipped(registry)
    else:
        directory, dir_option = Path(args.dir), f" --dir {args.dir}"
    if args.check:
        problems = schema_diff(registry, directory)
        for problem in problems:
            _err(problem)
        if problems:
            _err(f"schemas are out of date: run `hapticframe schema --write{dir_option}`")
            return 1
        _out(f"{directory}: schemas are up to date")
        return 0
    if args.write:
        written = write_schemas(registry, directory)
        _out(f"wrote {len(written)} schema files under {directory}")
        return 0
    _out(render_schemas(registry)["experiment.schema.json"].rstrip())
    return 0


def cmd_check(args: argparse.Namespace) -> int:
    from ._errors import UsageError
    from ._kind import Kind
    from .testing import run_checks

    registry = _manager(args).registry
    selected = []
    for name in args.names:
        found = registry.find(name)
        if args.kind:
            found = [r for r in found if r.spec.kind is Kind(args.kind)]
        if not found:
            if args.kind:
                raise UsageError(registry.unknown_message(Kind(args.kind), name))
            raise UsageError(_unknown_plugin_message(registry, name))
        selected.extend(found)
    failures = 0
    for reg in selected:
        for result in run_checks(reg.spec, registry=registry):
            _out(f"{result.status:<5} {reg.spec.kind}/{reg.spec.name}::{result.check}"
                 + (f"  {result.message}" if result.message and result.status != "PASS" else ""))
            failures += result.status == "FAIL"
    _out(f"{failures} check(s) failed" if failures else "all checks passed")
    return 1 if failures else 0


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


def _summary(metrics: Any, label_channel: str = "contact") -> str:
    """The few figures a person reads after a run: search result, force, accuracy, time
    (``contact`` in the names stands for ``run.label_channel``)."""
    wanted = [k.replace("contact_", f"{label_channel}_", 1) for k in SUMMARY_METRICS]
    parts = []
    for key in wanted:
        value = metrics.get(key)
        if isinstance(value, bool):
            parts.append(f"{key}={'yes' if value else 'no'}")
        elif isinstance(value, (int, float)) and not math.isnan(value):  # NaN: metrics.json
            parts.append(f"{key}={_short(value)}")
    return ", ".join(parts)


def _unknown_plugin_message(registry: Any, name: str) -> str:
    """No plugin of any kind is called ``name``: say so, with close names."""
    import difflib

    names = sorted({reg.spec.name for reg in registry})
    close = difflib.get_close_matches(name, names, n=3, cutoff=0.5)
    hint = f"; did you mean {' or '.join(repr(c) for c in close)}?" if close else ""
    return f"no plugin called {name!r} is installed{hint} (see `hapticframe plugins`)"


def cmd_run(args: argparse.Namespace) -> int:
    from ._run import run_experiment

    experiment = _validate(args, args.file)
    if getattr(args, "live", False):
        return _run_live(args, experiment)
    echo = (lambda _text: None) if args.quiet else _progress_line
    metrics = run_experiment(experiment, args.out, overwrite=args.overwrite, echo=echo,
                             progress=not args.quiet, min_free_bytes=_min_free(args))
    label_channel = experiment.model.run.label_channel
    _out(f"results in {args.out} (all metrics in metrics.json): "
         + _summary(metrics, label_channel))
    return 0


def _wait_for_interrupt() -> None:
    """Block until Ctrl-C (the live page keeps serving meanwhile)."""
    import threading

    forever = threading.Event()
    try:
        while not forever.wait(3600):
            pass
    except KeyboardInterrupt:
        pass


def _run_live(args: argparse.Namespace, experiment: Any) -> int:
    """``run --live``: the run with its page; however the run ends, the page stays up with
    its last picture and the run's status until Ctrl-C (:func:`hapticframe._live.run_live`),
    then the run's error, if any, is the command's."""
    from ._errors import UsageError
    from ._live import run_live
    from ._run import run_experiment

    if not experiment.model.run.record:
        raise UsageError("--live shows the run's recording, which this experiment turns off "
                         "(run.record: false); remove that line or drop --live")
    echo = (lambda _text: None) if args.quiet else _progress_line
    label = experiment.model.run.label_channel
    run_live(
        experiment,
        lambda: run_experiment(experiment, args.out, overwrite=args.overwrite, echo=echo,
                               progress=not args.quiet, min_free_bytes=_min_free(args)),
        port=_port_of(args), say=_out, wait=_wait_for_interrupt,
        finished=lambda m: _out(f"results in {args.out} (all metrics in metrics.json): "
                                + _summary(m, label)),
    )
    return 0


def cmd_view(args: argparse.Namespace) -> int:
    from ._errors import UsageError
    from ._live import LiveServer, RecordingTimeline, TimelineFeed
    from ._recording import find_recording, read_recording

    path = find_recording(Path(args.target))
    timeline = RecordingTimeline.from_recording(read_recording(path))
    if not timeline.messages:
        raise UsageError(f"{path} holds no messages to view")
    server = LiveServer(TimelineFeed(timeline, name=str(args.target)), port=_port_of(args))
    url = server.start()
    _out(f"viewing {path}: {len(timeline.messages)} messages, t = {timeline.start_s:.3f} ... "
         f"{timeline.end_s:.3f} s, at {url} (Ctrl-C stops it)")
    _wait_for_interrupt()
    server.stop()
    return 0


def cmd_recover(args: argparse.Namespace) -> int:
    from ._recording import recover_run

    recovery = recover_run(Path(args.target), Path(args.out) if args.out else None)
    how = f"cut short: {recovery.cut}" if recovery.cut else "complete"
    _out(f"read {recovery.source} ({how})")
    for topic, count in sorted(recovery.counts.items()):
        _out(f"  {topic}: {count} messages")
    _out(f"wrote {recovery.target}: {recovery.messages} messages on {len(recovery.counts)} "
         f"channels, t = {recovery.start_s:.3f} ... {recovery.end_s:.3f} s")
    return 0


def cmd_import_bag(args: argparse.Namespace) -> int:
    from ._bags import describe, import_bag, parse_map

    maps = [parse_map(text) for text in args.map or ()]
    result = import_bag(args.bag, maps, args.out, overwrite=args.overwrite,
                        min_free_bytes=_min_free(args))
    _out(f"read {result.bag}")
    for line in describe(result):
        _out(line)
    return 0


def cmd_replay(args: argparse.Namespace) -> int:
    from ._replay import replay_run

    experiment = _validate(args, args.with_file)
    echo = (lambda _text: None) if args.quiet else _progress_line
    metrics = replay_run(args.target, experiment, args.out, overwrite=args.overwrite,
                         echo=echo, progress=not args.quiet, min_free_bytes=_min_free(args))
    _out(f"replay results in {args.out} (all metrics in metrics.json): "
         + _summary(metrics, experiment.model.run.label_channel))
    return 0


def cmd_report(args: argparse.Namespace) -> int:
    from ._report import write_report

    report = write_report(Path(args.target), Path(args.out) if args.out else None,
                          figures=not args.no_figures)
    how = f", cut short: {report.cut}" if report.cut else ""
    _out(f"read {report.source} ({report.messages} messages{how})")
    _out(f"wrote {', '.join(report.files)} into {report.out}")
    return 0


def cmd_train(args: argparse.Namespace) -> int:
    from ._train import train_experiment

    experiment = _validate(args, args.file, command="train")
    record = train_experiment(experiment, args.out, overwrite=args.overwrite,
                              echo=_progress_line, min_free_bytes=_min_free(args))
    _out(f"trained {', '.join(record['trained']) or 'nothing'}; artifacts in {args.out}")
    return 0


def _min_free(args: argparse.Namespace) -> int | None:
    """``--min-free-mb`` in bytes; None: the default (HAPTICFRAME_MIN_FREE_MB or 50 MB)."""
    megabytes = getattr(args, "min_free_mb", None)
    return None if megabytes is None else int(megabytes * 1024 * 1024)


def _megabytes(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number of megabytes") from None
    if not math.isfinite(value) or value < 0:
        raise argparse.ArgumentTypeError("must be a finite number of megabytes, at least 0")
    return value


def _add_out_options(p: argparse.ArgumentParser, what: str, replaces: str) -> None:
    p.add_argument("--out", required=True, metavar="DIR", help=f"directory for {what}")
    p.add_argument("--overwrite", action="store_true",
                   help=f"delete {replaces} already in DIR first (only files hapticframe "
                   "wrote and listed; refused when DIR holds others)")
    p.add_argument("--min-free-mb", type=_megabytes, default=None, metavar="MB",
                   help="free space DIR must have before anything runs (default: "
                   "HAPTICFRAME_MIN_FREE_MB or 50)")


def _port(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a port number") from None
    if not 0 <= value <= 65535:
        raise argparse.ArgumentTypeError("must be 0 (any free port) ... 65535")
    return value


#: The live page's port when --port is not given (kept here: the parser imports nothing).
LIVE_PORT = 8765


def _add_port_option(p: argparse.ArgumentParser) -> None:
    p.add_argument("--port", type=_port, default=None,
                   help=f"the live page's port on 127.0.0.1 (default {LIVE_PORT}; 0: any "
                   "free port; printed at start)")


def _port_of(args: argparse.Namespace) -> int:
    port: int | None = getattr(args, "port", None)
    return LIVE_PORT if port is None else port


def _short(value: float) -> str:
    return f"{value:.4g}" if isinstance(value, float) else str(value)


def cmd_bench(args: argparse.Namespace) -> int:
    from ._bench import BenchOptions, list_benches, run_bench

    if args.name is None:
        for line in list_benches():
            _out(line)
        return 0
    options = BenchOptions(
        out_dir=Path(args.out), trials=args.trials, seed=args.seed, quick=args.quick,
        workers=args.workers, device=args.device, echo=_out,
        overrides=tuple(o.text for o in args.set),
    )
    run_bench(args.name, options)
    return 0


def _vary(text: str) -> Any:
    """A ``--vary PATH=V1,V2,...`` (see :mod:`hapticframe._sweep`), parsed when read."""
    from ._errors import UsageError
    from ._sweep import parse_vary

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
    from ._sweep import SweepOptions, run_sweep

    options = SweepOptions(
        varies=tuple(args.vary), declared=args.declared, grid=args.grid, trials=args.trials,
        workers=args.workers, timeout_s=args.timeout_s, executor=args.executor,
        scheduler=args.scheduler, overrides=tuple(args.set),
        plugin_modules=tuple(args.plugin_module or ()), echo=_progress_line,
    )
    result = run_sweep(args.file, args.out, options)
    failed = [p for p in result["points"] if p["status"] != "ok"]
    front = ", ".join(result["front"]) or "none"
    _out(f"{len(result['points'])} points, {len(failed)} failed or refused; Pareto front: "
         f"{front}; table in {Path(args.out) / 'sweep.md'}")
    return 0


# --- parser ----------------------------------------------------------------------------------


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="hapticframe",
        description="Find objects buried in granular media by touch: assemble and run "
        "experiments from plugins.",
    )
    parser.add_argument("--debug", action="store_true", help="show tracebacks")
    parser.add_argument("--version", action="store_true", help="print the version and exit")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")

    p = sub.add_parser("plugins", help="list installed plugins (kind, name, distribution, status)")
    p.add_argument("--strict", action="store_true", help="fail if any plugin fails to load")
    p.add_argument("--json", action="store_true",
                   help="machine-readable output (each plugin with its knobs)")
    p.add_argument("--knobs", action="store_true",
                   help="list each plugin's speed/accuracy knobs (field, values, trade) instead")
    _add_plugin_module_option(p)
    p.set_defaults(func=cmd_plugins)

    p = sub.add_parser("validate", help="check experiment files without running them")
    p.add_argument("files", nargs="+", metavar="FILE")
    p.add_argument("--strict", action="store_true", help="fail if any plugin fails to load")
    _add_set_option(p)
    _add_plugin_module_option(p)
    p.set_defaults(func=cmd_validate)

    p = sub.add_parser("schema", help="print, write or check the JSON Schemas")
    group = p.add_mutually_exclusive_group()
    group.add_argument("--write", action="store_true", help="write the schema files")
    group.add_argument("--check", action="store_true", help="exit 1 if the files are stale")
    p.add_argument("--dir", default=None, metavar="DIR",
                   help="schema directory for every installed plugin, a lab's own included "
                   "(default: schemas/, for the plugins hapticframe ships)")
    p.set_defaults(func=cmd_schema)

    p = sub.add_parser("check", help="run the conformance kit on installed plugins")
    p.add_argument("names", nargs="+", metavar="NAME")
    p.add_argument("--kind", choices=[k.value for k in _kinds()], help="only plugins of this kind")
    _add_plugin_module_option(p)
    p.set_defaults(func=cmd_check)

    p = sub.add_parser("run", help="assemble and run an experiment")
    p.add_argument("file", metavar="FILE")
    _add_out_options(p, "results", "the results of a run")
    p.add_argument("--quiet", action="store_true", help="no progress lines")
    p.add_argument("--strict", action="store_true", help="fail if any plugin fails to load")
    _add_set_option(p)
    p.add_argument("--live", action="store_true",
                   help="serve a page on 127.0.0.1 that shows the run as it runs (map, path, "
                   "force, class probabilities, metrics); it stays up after the run until "
                   "Ctrl-C (needs hapticframe[live])")
    _add_port_option(p)
    _add_plugin_module_option(p)
    p.set_defaults(func=cmd_run)

    p = sub.add_parser("recover", help="rewrite a killed run's recording as a complete one")
    p.add_argument("target", metavar="DIR",
                   help="a run's --out directory (its run.mcap, or the one a killed run left "
                   "in .hapticframe-partial/) or an .mcap file")
    p.add_argument("--out", default=None, metavar="FILE",
                   help="where to write it (default: DIR/run.mcap, or the file itself)")
    p.set_defaults(func=cmd_recover)

    p = sub.add_parser("import-bag", help="turn a ROS 1 or ROS 2 bag's sensor topics into a "
                       "recording the `recording` sensor source reads")
    p.add_argument("bag", metavar="BAG",
                   help="a ROS 1 .bag file or a ROS 2 bag directory (sqlite3 or mcap storage)")
    p.add_argument("--map", action="append", metavar="TOPIC=SENSOR_ID",
                   help="a topic (WrenchStamped, Imu or BioTacHand) to record as sensor "
                   "SENSOR_ID (repeatable); TOPIC:FINGER=SENSOR_ID picks one finger of a "
                   "BioTac hand by bt_position or bt_serial")
    _add_out_options(p, "the recording (run.mcap) and import.json", "an earlier import")
    p.set_defaults(func=cmd_import_bag)

    from ._cli_import import register as register_import
    register_import(sub, _add_out_options)

    p = sub.add_parser("replay", help="re-run a recorded run's perception and mapping with "
                       "an experiment's classifiers, sensor models and maps")
    p.add_argument("target", metavar="DIR",
                   help="a run's --out directory (its run.mcap) or a run.mcap file")
    p.add_argument("--with", dest="with_file", required=True, metavar="EXPERIMENT",
                   help="the experiment whose perception chain to replay (the run's own file "
                   "reproduces its metrics.json)")
    _add_out_options(p, "results", "the results of a replay")
    _add_set_option(p, "the --with experiment")
    p.add_argument("--quiet", action="store_true", help="no progress lines")
    p.add_argument("--strict", action="store_true", help="fail if any plugin fails to load")
    _add_plugin_module_option(p)
    p.set_defaults(func=cmd_replay)

    p = sub.add_parser("view", help="serve the live page for a finished or recovered run, "
                       "with a time slider")
    p.add_argument("target", metavar="DIR",
                   help="a run's --out directory (its run.mcap, or the one a killed run left "
                   "in .hapticframe-partial/) or an .mcap file")
    _add_port_option(p)
    p.set_defaults(func=cmd_view)

    p = sub.add_parser("report", help="write trace.npz and figures from a run's recording")
    p.add_argument("target", metavar="DIR",
                   help="a run's --out directory (its run.mcap, or the one a killed run left "
                   "in .hapticframe-partial/) or an .mcap file")
    p.add_argument("--out", default=None, metavar="DIR",
                   help="where to write them (default: DIR, or the file's folder)")
    p.add_argument("--no-figures", action="store_true", help="write trace.npz only")
    p.set_defaults(func=cmd_report)

    p = sub.add_parser("train", help="fit an experiment's trainable components on its recordings")
    p.add_argument("file", metavar="FILE")
    _add_out_options(p, "the artifacts", "the artifacts of a training run")
    p.add_argument("--strict", action="store_true", help="fail if any plugin fails to load")
    _add_set_option(p)
    _add_plugin_module_option(p)
    p.set_defaults(func=cmd_train)

    p = sub.add_parser("bench", help="run a benchmark suite (see `hapticframe plugins`)")
    p.add_argument("name", metavar="NAME", nargs="?", help="the suite to run; none: list them")
    p.add_argument("--trials", type=_positive_int, default=None, help="trials per case")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--out", default="bench-out", metavar="DIR")
    p.add_argument("--quick", action="store_true", help="a reduced run")
    p.add_argument("--workers", type=_positive_int, default=None,
                   help="processes for independent trials (default: one per CPU)")
    p.add_argument("--device", default="cpu",
                   help="where a suite that trains models trains them: cpu (default) or a "
                   "torch accelerator such as cuda")
    _add_set_option(p, "every experiment the suite runs (suites that run experiment "
                    "files: search)")
    p.set_defaults(func=cmd_bench)

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
    p.add_argument("--trials", type=_positive_int, default=3,
                   help="seeded trials per point: seed, seed + 1, ... (default 3)")
    p.add_argument("--out", required=True, metavar="DIR",
                   help="directory for sweep.json, sweep.md, pareto.png and the runs")
    p.add_argument("--workers", type=_positive_int, default=None,
                   help="worker processes (default: one per CPU)")
    p.add_argument("--timeout-s", type=_seconds, default=None, metavar="T",
                   help="a trial running longer is a 'timeout' row (default: no limit)")
    p.add_argument("--executor", choices=("process", "dask"), default="process",
                   help="process: a local process pool (default); dask: a Dask cluster "
                   "(--scheduler, else a LocalCluster; needs hapticframe[distributed])")
    p.add_argument("--scheduler", default=None, metavar="ADDRESS",
                   help="the Dask scheduler, e.g. tcp://head-node:8786 (--executor dask)")
    _add_set_option(p, "every point")
    _add_plugin_module_option(p)
    p.set_defaults(func=cmd_sweep)
    return parser


def _kinds() -> list[Any]:
    from ._kind import Kind

    return list(Kind)


def _positive_int(text: str) -> int:
    value = int(text)
    if value < 1:
        raise argparse.ArgumentTypeError("must be at least 1")
    return value


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of ``hapticframe`` and ``python -m hapticframe``."""
    parser = _parser()
    args = parser.parse_args(argv)
    if args.version:
        from ._version import __version__

        _out(f"hapticframe {__version__}")
        return 0
    if not getattr(args, "func", None):
        parser.print_help()
        return 2
    handler = _configure_logging(args.debug)
    try:
        # One-line warnings for this command only: catch_warnings restores the process's
        # own showwarning when the command returns.
        with warnings.catch_warnings():
            warnings.showwarning = _one_line_warning
            return _dispatch(args)
    except BrokenPipeError:
        return _closed_pipe()
    finally:
        logging.getLogger("hapticframe").removeHandler(handler)


def _closed_pipe() -> int:
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


def _dispatch(args: argparse.Namespace) -> int:
    from ._errors import HapticframeError, RunInterrupted

    try:
        return int(args.func(args))
    except BrokenPipeError:
        raise
    except RunInterrupted as exc:
        _err(f"interrupted ({exc.signal_name}); the run's run.json records it")
        return exc.exit_code
    except HapticframeError as exc:
        if args.debug:
            raise
        _err(f"error: {exc}" if "\n" not in str(exc) else str(exc))
        _hints(exc)
        return exc.exit_code
    except KeyboardInterrupt:
        _err("interrupted")
        return 130
    except Exception as exc:  # a bug: one line, the traceback with --debug
        if args.debug:
            raise
        _err(f"internal error: {type(exc).__name__}: {exc} (rerun with --debug for the traceback)")
        return 1


def _hints(exc: BaseException) -> None:
    try:
        from ._manager import get_plugin_manager

        for hints in get_plugin_manager().hook.hapticframe_error_hints(error=exc):
            for hint in hints or ():
                _err(f"hint: {hint}")
    except Exception:  # hints must never hide the error itself
        pass


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
