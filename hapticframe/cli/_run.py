"""``hapticframe run``: assemble and run an experiment."""

from __future__ import annotations

import argparse
from typing import Any

from hapticframe._defaults import FOXGLOVE_PORT
from hapticframe.cli._common import (
    add_out_options,
    add_plugin_module_option,
    add_port_option,
    add_set_option,
    err,
    min_free,
    out,
    port_arg,
    port_of,
    progress_line,
    searches,
    summary_line,
    validate_experiment,
    wait_for_interrupt,
)

__all__ = ["register"]


def register(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Add ``hapticframe run`` to the command line."""
    p = sub.add_parser("run", help="assemble and run an experiment")
    p.add_argument("file", metavar="FILE")
    add_out_options(p, "results", "the results of a run")
    p.add_argument("--quiet", action="store_true", help="no progress lines")
    p.add_argument("--strict", action="store_true", help="fail if any plugin fails to load")
    add_set_option(p)
    p.add_argument("--live", action="store_true",
                   help="serve a page on 127.0.0.1 that shows the run as it runs (map, path, "
                   "force, class probabilities, metrics); it stays up after the run until "
                   "Ctrl-C (needs hapticframe[live])")
    add_port_option(p)
    p.add_argument("--foxglove", nargs="?", const=FOXGLOVE_PORT, default=None, type=_foxglove_port,
                   metavar="PORT",
                   help="serve the run over Foxglove's WebSocket protocol on 127.0.0.1 while "
                   f"it runs, the channels of run.mcap (default port {FOXGLOVE_PORT}; 0: any "
                   "free port; the ws:// address is printed at start; put it after FILE; "
                   "needs hapticframe[foxglove])")
    add_plugin_module_option(p)
    p.set_defaults(func=cmd_run)


def _foxglove_port(text: str) -> int:
    """``--foxglove``'s optional PORT (argparse takes the next word for it, the FILE too)."""
    try:
        return port_arg(text)
    except argparse.ArgumentTypeError as exc:
        raise argparse.ArgumentTypeError(f"{exc} (write --foxglove after FILE, or give its "
                                         "PORT)") from None


def cmd_run(args: argparse.Namespace) -> int:
    experiment = validate_experiment(args, args.file)
    bridge = _foxglove_bridge(args, experiment)
    if bridge is None:
        return _run(args, experiment)
    from hapticframe.record._recording import listening

    # The same hook as --live: the bridge sees every message the run's recording writes.
    with bridge, listening(bridge):
        status = _run(args, experiment)
        out(f"foxglove: the run has ended; the server at {bridge.url} closes (the whole run: "
            f"open {args.out}/run.mcap in Foxglove)")
        return status


def _foxglove_bridge(args: argparse.Namespace, experiment: Any) -> Any:
    """``--foxglove [PORT]``: the started server (before the run, so that a missing SDK or a
    taken port is a usage error with nothing run), or None without the option."""
    port: int | None = getattr(args, "foxglove", None)
    if port is None:
        return None
    from hapticframe._errors import UsageError

    if getattr(args, "live", False) and port != 0 and port == port_of(args):
        raise UsageError(f"--foxglove {port} is the live page's port too (--port, default "
                         f"{port_of(args)}); give one of them another: e.g. --foxglove "
                         f"{port + 1}, or 0 for any free port")
    if not experiment.model.run.record:
        raise UsageError("--foxglove serves the run's recording, which this experiment turns "
                         "off (run.record: false); remove that line or drop --foxglove")
    from hapticframe.live._foxglove import FoxgloveBridge

    bridge = FoxgloveBridge(port)
    out(f"foxglove: {bridge.url} (Foxglove: Open connection, Foxglove WebSocket; served "
        "while the run runs)")
    return bridge


def _run(args: argparse.Namespace, experiment: Any) -> int:
    from hapticframe.record._recorded import run_experiment

    if getattr(args, "live", False):
        return _run_live(args, experiment)
    from hapticframe.run._verdict import RunInconclusive

    echo = (lambda _text: None) if args.quiet else progress_line
    label_channel = experiment.model.run.label_channel
    try:
        metrics = run_experiment(experiment, args.out, overwrite=args.overwrite, echo=echo,
                                 progress=not args.quiet, min_free_bytes=min_free(args))
    except RunInconclusive as exc:
        # The run wrote its files: say where, what they show, and why they are no result.
        out(f"results in {args.out} (all metrics in metrics.json): "
            + summary_line(exc.metrics, label_channel, searched=searches(experiment)))
        err(f"error: {exc} (run.json: status failed)")
        return exc.exit_code
    out(f"results in {args.out} (all metrics in metrics.json): "
         + summary_line(metrics, label_channel, searched=searches(experiment)))
    return 0


def _run_live(args: argparse.Namespace, experiment: Any) -> int:
    """``run --live``: the run with its page; however the run ends, the page stays up with
    its last picture and the run's status until Ctrl-C (:func:`hapticframe.live.run_live`),
    then the run's error, if any, is the command's."""
    from hapticframe._errors import UsageError
    from hapticframe.live import run_live
    from hapticframe.record._recorded import run_experiment

    if not experiment.model.run.record:
        raise UsageError("--live shows the run's recording, which this experiment turns off "
                         "(run.record: false); remove that line or drop --live")
    echo = (lambda _text: None) if args.quiet else progress_line
    label = experiment.model.run.label_channel
    run_live(
        experiment,
        lambda: run_experiment(experiment, args.out, overwrite=args.overwrite, echo=echo,
                               progress=not args.quiet, min_free_bytes=min_free(args)),
        port=port_of(args), say=out, wait=wait_for_interrupt,
        finished=lambda m: out(f"results in {args.out} (all metrics in metrics.json): "
                                + summary_line(m, label, searched=searches(experiment))),
    )
    return 0

