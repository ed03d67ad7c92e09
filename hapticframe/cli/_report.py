"""``hapticframe report``: a trace and figures from a run's recording, beside the run's own."""

from __future__ import annotations

import argparse
from pathlib import Path

from hapticframe.cli._common import (
    out,
)

__all__ = ["register"]


def register(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Add ``hapticframe report`` to the command line."""
    p = sub.add_parser("report", help="write a trace (report_trace.npz) and figures from a "
                       "run's recording, beside the run's own results")
    p.add_argument("target", metavar="DIR",
                   help="a run's --out directory (its run.mcap, or the one a killed run left "
                   "in .hapticframe-partial/) or an .mcap file")
    p.add_argument("--out", default=None, metavar="DIR",
                   help="where to write them (default: DIR, or the file's folder)")
    p.add_argument("--no-figures", action="store_true", help="write report_trace.npz only")
    p.set_defaults(func=cmd_report)


def cmd_report(args: argparse.Namespace) -> int:
    from hapticframe.record._report import write_report

    report = write_report(Path(args.target), Path(args.out) if args.out else None,
                          figures=not args.no_figures)
    how = f", cut short: {report.cut}" if report.cut else ""
    out(f"read {report.source} ({report.messages} messages{how})")
    out(f"wrote {', '.join(report.files)} into {report.out}")
    return 0

