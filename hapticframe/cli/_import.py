"""``hapticframe import``: tabular trials (xlsx sheets, CSV files, HDF5 groups) by a layout
file, as a recording the ``trace-recording`` and ``recording`` sensors replay."""

from __future__ import annotations

import argparse

from hapticframe.cli._common import add_out_options, min_free, out

__all__ = ["cmd_import", "register"]


def register(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Add ``hapticframe import`` to the command line."""
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


def cmd_import(args: argparse.Namespace) -> int:
    from hapticframe.record._table_import import describe_import, import_tables

    result = import_tables(args.tables, args.layout, args.out, overwrite=args.overwrite,
                           min_free_bytes=min_free(args))
    for line in describe_import(result):
        out(line)
    return 0
