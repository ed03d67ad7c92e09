"""``hapticframe train``: fit an experiment's trainable components on its recordings."""

from __future__ import annotations

import argparse

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
    add_set_option(p)
    add_plugin_module_option(p)
    p.set_defaults(func=cmd_train)


def cmd_train(args: argparse.Namespace) -> int:
    from hapticframe.run._train import train_experiment

    experiment = validate_experiment(args, args.file, command="train")
    record = train_experiment(experiment, args.out, overwrite=args.overwrite,
                              echo=progress_line, min_free_bytes=min_free(args))
    out(f"trained {', '.join(record['trained']) or 'nothing'}; artifacts in {args.out}")
    return 0

