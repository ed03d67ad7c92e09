"""``hapticframe view``: serve the live page for a finished or recovered run, ."""

from __future__ import annotations

import argparse
from pathlib import Path

from hapticframe.cli._common import (
    add_port_option,
    out,
    port_of,
    wait_for_interrupt,
)

__all__ = ["register"]


def register(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Add ``hapticframe view`` to the command line."""
    p = sub.add_parser("view", help="serve the live page for a finished or recovered run, "
                       "with a time slider")
    p.add_argument("target", metavar="DIR",
                   help="a run's --out directory (its run.mcap, or the one a killed run left "
                   "in .hapticframe-partial/) or an .mcap file")
    add_port_option(p)
    p.set_defaults(func=cmd_view)


def cmd_view(args: argparse.Namespace) -> int:
    from hapticframe._errors import UsageError
    from hapticframe.live import LiveServer, RecordingTimeline, TimelineFeed
    from hapticframe.record._recording import find_recording, read_recording

    path = find_recording(Path(args.target))
    timeline = RecordingTimeline.from_recording(read_recording(path))
    if not timeline.messages:
        raise UsageError(f"{path} holds no messages to view")
    server = LiveServer(TimelineFeed(timeline, name=str(args.target)), port=port_of(args))
    url = server.start()
    out(f"viewing {path}: {len(timeline.messages)} messages, t = {timeline.start_s:.3f} ... "
         f"{timeline.end_s:.3f} s, at {url} (Ctrl-C stops it)")
    wait_for_interrupt()
    server.stop()
    return 0

