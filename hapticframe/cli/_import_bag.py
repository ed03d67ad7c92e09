"""``hapticframe import-bag``: turn a ROS 1 or ROS 2 bag's sensor topics into a ."""

from __future__ import annotations

import argparse

from hapticframe.cli._common import (
    add_out_options,
    min_free,
    out,
)

__all__ = ["register"]


def register(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Add ``hapticframe import-bag`` to the command line."""
    p = sub.add_parser("import-bag", help="turn a ROS 1 or ROS 2 bag's sensor topics into a "
                       "recording the `recording` sensor source reads")
    p.add_argument("bag", metavar="BAG",
                   help="a ROS 1 .bag file or a ROS 2 bag directory (sqlite3 or mcap storage)")
    p.add_argument("--map", action="append", metavar="TOPIC=SENSOR_ID",
                   help="a topic (WrenchStamped, Imu or BioTacHand) to record as sensor "
                   "SENSOR_ID (repeatable); TOPIC:FINGER=SENSOR_ID picks one finger of a "
                   "BioTac hand by bt_position or bt_serial")
    add_out_options(p, "the recording (run.mcap) and import.json", "an earlier import")
    p.set_defaults(func=cmd_import_bag)


def cmd_import_bag(args: argparse.Namespace) -> int:
    from hapticframe.record._bags import describe, import_bag, parse_map

    maps = [parse_map(text) for text in args.map or ()]
    result = import_bag(args.bag, maps, args.out, overwrite=args.overwrite,
                        min_free_bytes=min_free(args))
    out(f"read {result.bag}")
    for line in describe(result):
        out(line)
    return 0

