"""``hapticframe recover``: rewrite a killed run's recording as a complete one."""

from __future__ import annotations

import argparse
from pathlib import Path

from hapticframe.cli._common import (
    out,
)

__all__ = ["register"]


def register(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Add ``hapticframe recover`` to the command line."""
    p = sub.add_parser("recover", help="rewrite a killed run's recording as a complete one")
    p.add_argument("target", metavar="DIR",
                   help="a run's --out directory (its run.mcap, or the one a killed run left "
                   "in .hapticframe-partial/) or an .mcap file")
    p.add_argument("--out", default=None, metavar="FILE",
                   help="where to write it (default: DIR/run.mcap, or the file itself)")
    p.set_defaults(func=cmd_recover)


def cmd_recover(args: argparse.Namespace) -> int:
    from hapticframe.record._recording import recover_run

    recovery = recover_run(Path(args.target), Path(args.out) if args.out else None)
    how = f"cut short: {recovery.cut}" if recovery.cut else "complete"
    out(f"read {recovery.source} ({how})")
    for topic, count in sorted(recovery.counts.items()):
        out(f"  {topic}: {count} messages")
    out(f"wrote {recovery.target}: {recovery.messages} messages on {len(recovery.counts)} "
         f"channels, t = {recovery.start_s:.3f} ... {recovery.end_s:.3f} s")
    return 0

