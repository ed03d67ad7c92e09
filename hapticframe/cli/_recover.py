"""``hapticframe recover``: what a killed run's (or a damaged) recording holds, written as a
complete one beside it."""

from __future__ import annotations

import argparse
from pathlib import Path

from hapticframe.cli._common import (
    out,
)

__all__ = ["register"]


def register(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Add ``hapticframe recover`` to the command line."""
    p = sub.add_parser("recover", help="write what a killed run's (or a damaged) recording "
                       "holds as a complete one, beside it")
    p.add_argument("target", metavar="DIR",
                   help="a run's --out directory (its run.mcap, or the one a killed run left "
                   "in .hapticframe-partial/) or an .mcap file")
    p.add_argument("--out", default=None, metavar="FILE",
                   help="where to write it (default: DIR/run.mcap for a killed run, else "
                   "NAME.recovered.mcap beside the file; never the file itself)")
    p.add_argument("--finished", action="store_true",
                   help="also read a finished run's run.mcap (a damaged one), writing "
                   "run.recovered.mcap beside it")
    p.set_defaults(func=cmd_recover)


def cmd_recover(args: argparse.Namespace) -> int:
    from hapticframe.record._recover import recover_run

    recovery = recover_run(Path(args.target), Path(args.out) if args.out else None,
                           finished=args.finished)
    how = f"cut short: {recovery.cut}" if recovery.cut else "read to its end"
    out(f"read {recovery.source} ({how})")
    for topic, count in sorted(recovery.counts.items()):
        out(f"  {topic}: {count} messages")
    for what in recovery.skipped:
        out(f"  skipped: {what}")
    out(f"wrote {recovery.target}: {recovery.messages} messages on {len(recovery.counts)} "
        f"channels, t = {recovery.start_s:.3f} ... {recovery.end_s:.3f} s"
        + (f"; moved in {', '.join(recovery.moved)}" if recovery.moved else ""))
    if recovery.next_step:
        out(f"next: {recovery.next_step}")
    return 0
