"""``hapticframe validate``: check experiment files without running them."""

from __future__ import annotations

import argparse

from hapticframe.cli._common import (
    add_plugin_module_option,
    add_set_option,
    err,
    out,
    validate_experiment,
)

__all__ = ["register"]


def register(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Add ``hapticframe validate`` to the command line."""
    p = sub.add_parser("validate", help="check experiment files without running them")
    p.add_argument("files", nargs="+", metavar="FILE")
    p.add_argument("--strict", action="store_true", help="fail if any plugin fails to load")
    add_set_option(p)
    add_plugin_module_option(p)
    p.set_defaults(func=cmd_validate)


def cmd_validate(args: argparse.Namespace) -> int:
    from hapticframe._errors import ExperimentError

    status = 0
    for file in args.files:
        try:
            experiment = validate_experiment(args, file)
        except ExperimentError as exc:
            err(exc.render())
            status = 2
            continue
        parts = ", ".join(f"{e.id} ({e.type})" for e in experiment.components)
        out(f"{file}: ok — {len(experiment.components)} components: {parts or 'none'}")
    return status

