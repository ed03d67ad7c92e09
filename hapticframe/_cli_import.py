"""The ``hapticframe import`` subcommand: tabular trials by a layout file, as a recording.

Kept apart from :mod:`hapticframe._cli` (one module per subcommand, issue 25).
"""

from __future__ import annotations

import argparse
from collections.abc import Callable
from typing import Any

__all__ = ["cmd_import", "register"]


def cmd_import(args: argparse.Namespace) -> int:
    from ._table_import import describe_import, import_tables

    min_free = getattr(args, "min_free_mb", None)
    result = import_tables(args.tables, args.layout, args.out, overwrite=args.overwrite,
                           min_free_bytes=None if min_free is None else int(min_free * 2**20))
    for line in describe_import(result):
        print(line, flush=True)
    return 0


def register(sub: Any, add_out_options: Callable[[argparse.ArgumentParser, str, str], None]
             ) -> None:
    """Add ``import`` to the CLI's subparsers (``add_out_options``: --out and its kin)."""
    p = sub.add_parser("import", help="turn tabular trials (xlsx sheets, CSV files, HDF5 "
                       "groups) into a recording, by a layout file")
    p.add_argument("tables", metavar="TABLES",
                   help="an .xlsx workbook (one trial per sheet), a .csv file or a directory "
                   "of them (one trial per file), or an .h5 file (one trial per group)")
    p.add_argument("--layout", required=True, metavar="FILE",
                   help="the YAML layout: which rows or columns are which channel, label and "
                   "position, with units and the rate (docs/recording.md)")
    add_out_options(p, "the recording (trace.npz, run.mcap) and import.json",
                    "an earlier import")
    p.set_defaults(func=cmd_import)
