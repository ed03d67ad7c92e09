"""``hapticframe replay``: re-run a recorded run's perception and mapping with ."""

from __future__ import annotations

import argparse

from hapticframe.cli._common import (
    add_out_options,
    add_plugin_module_option,
    add_set_option,
    min_free,
    out,
    progress_line,
    searches,
    summary_line,
    validate_experiment,
)

__all__ = ["register"]


def register(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Add ``hapticframe replay`` to the command line."""
    p = sub.add_parser("replay", help="re-run a recorded run's perception and mapping with "
                       "an experiment's classifiers, sensor models and maps")
    p.add_argument("target", metavar="DIR",
                   help="a run's --out directory (its run.mcap) or a run.mcap file")
    p.add_argument("--with", dest="with_file", required=True, metavar="EXPERIMENT",
                   help="the experiment whose perception chain to replay (the run's own file "
                   "reproduces its metrics.json)")
    add_out_options(p, "results", "the results of a replay")
    add_set_option(p, "the --with experiment")
    p.add_argument("--quiet", action="store_true", help="no progress lines")
    p.add_argument("--strict", action="store_true", help="fail if any plugin fails to load")
    add_plugin_module_option(p)
    p.set_defaults(func=cmd_replay)


def cmd_replay(args: argparse.Namespace) -> int:
    from hapticframe.record._replay import replay_run

    experiment = validate_experiment(args, args.with_file)
    echo = (lambda _text: None) if args.quiet else progress_line
    metrics = replay_run(args.target, experiment, args.out, overwrite=args.overwrite,
                         echo=echo, progress=not args.quiet, min_free_bytes=min_free(args))
    out(f"replay results in {args.out} (all metrics in metrics.json): "
         + summary_line(metrics, experiment.model.run.label_channel,
                        searched=searches(experiment)))
    return 0

