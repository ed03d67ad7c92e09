"""``hapticframe train``: fit an experiment's trainable components on its recordings."""

from __future__ import annotations

import argparse
import json

from hapticframe.cli._common import (
    add_out_options,
    add_plugin_module_option,
    add_set_option,
    min_free,
    out,
    progress_line,
    validate_experiment,
)

__all__ = ["register"]


def register(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Add ``hapticframe train`` to the command line."""
    p = sub.add_parser("train", help="fit an experiment's trainable components on its recordings")
    p.add_argument("file", metavar="FILE")
    add_out_options(p, "the artifacts", "the artifacts of a training run")
    p.add_argument("--strict", action="store_true", help="fail if any plugin fails to load")
    p.add_argument(
        "--calibration", action="append", default=[], metavar="RUN_DIR",
        help="a recorded calibration run (a run's --out directory over an object buried "
        "where you know it) to fit the sensor models that learn from them; repeatable, "
        "replaces the file's run.calibration_runs")
    add_set_option(p)
    add_plugin_module_option(p)
    p.set_defaults(func=cmd_train)


def cmd_train(args: argparse.Namespace) -> int:
    from hapticframe.run._train import train_experiment

    if args.calibration:
        from hapticframe._config._overrides import Override

        runs = [str(d) for d in args.calibration]
        # As the last --set: it replaces the file's list, recorded in train.json's overrides.
        args.set = [*args.set, Override("run.calibration_runs", runs,
                                        "run.calibration_runs=" + json.dumps(runs))]
    experiment = validate_experiment(args, args.file, command="train")
    record = train_experiment(experiment, args.out, overwrite=args.overwrite,
                              echo=progress_line, min_free_bytes=min_free(args))
    out(f"trained {', '.join(record['trained']) or 'nothing'}; artifacts in {args.out}")
    return 0

