"""``hapticframe schema``: print, write or check the JSON Schemas."""

from __future__ import annotations

import argparse
from pathlib import Path

from hapticframe.cli._common import (
    err,
    out,
)

__all__ = ["register"]


def register(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Add ``hapticframe schema`` to the command line."""
    p = sub.add_parser("schema", help="print, write or check the JSON Schemas")
    group = p.add_mutually_exclusive_group()
    group.add_argument("--write", action="store_true", help="write the schema files")
    group.add_argument("--check", action="store_true", help="exit 1 if the files are stale")
    p.add_argument("--dir", default=None, metavar="DIR",
                   help="schema directory for every installed plugin, a lab's own included "
                   "(default: schemas/, for the plugins hapticframe ships)")
    p.set_defaults(func=cmd_schema)


def cmd_schema(args: argparse.Namespace) -> int:
    from hapticframe._manager import get_registry
    from hapticframe._schema import render_schemas, schema_diff, shipped, write_schemas

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
            err(problem)
        if problems:
            err(f"schemas are out of date: run `hapticframe schema --write{dir_option}`")
            return 1
        out(f"{directory}: schemas are up to date")
        return 0
    if args.write:
        written = write_schemas(registry, directory)
        out(f"wrote {len(written)} schema files under {directory}")
        return 0
    out(render_schemas(registry)["experiment.schema.json"].rstrip())
    return 0

