"""``hapticframe plugins``: list installed plugins (kind, name, distribution, status)."""

from __future__ import annotations

import argparse
from typing import Any

from hapticframe.cli._common import (
    add_plugin_module_option,
    out,
    plugin_manager,
)

__all__ = ["register"]


def register(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Add ``hapticframe plugins`` to the command line."""
    p = sub.add_parser("plugins", help="list installed plugins (kind, name, distribution, status)")
    p.add_argument("--strict", action="store_true", help="fail if any plugin fails to load")
    p.add_argument("--json", action="store_true",
                   help="machine-readable output (each plugin with its knobs)")
    p.add_argument("--knobs", action="store_true",
                   help="list each plugin's speed/accuracy knobs (field, values, trade) instead")
    p.add_argument("--channels", action="store_true",
                   help="list what each plugin produces and consumes (channel, shape, unit, "
                   "use) instead")
    add_plugin_module_option(p)
    p.set_defaults(func=cmd_plugins)


def cmd_plugins(args: argparse.Namespace) -> int:
    pm = plugin_manager(args, strict=args.strict)
    registry = pm.registry
    rows, regs = [], list(registry)
    for reg in regs:
        missing = reg.missing_requirements
        conflicted = any((c.kind, c.name) == reg.spec.key for c in registry.conflicts)
        status = "conflict" if conflicted else (
            f"needs {', '.join(missing)}" if missing else "ok"
        )
        rows.append((str(reg.spec.kind), reg.spec.name, reg.source.distribution,
                     reg.source.version, status, reg.spec.summary))
    if args.json:
        import json

        from hapticframe._knobs import RUN_KNOBS, knob_record

        data = {
            "plugins": [
                dict(zip(("kind", "name", "distribution", "version", "status", "summary"), r,
                         strict=True), knobs=[knob_record(k) for k in reg.spec.knobs],
                     produces=_channel_records(reg.spec.produces),
                     consumes=_channel_records(reg.spec.reads))
                for r, reg in zip(rows, regs, strict=True)
            ],
            "run_knobs": [knob_record(k) for k in RUN_KNOBS],
            "benchmarks": sorted(registry.benchmarks),
            "broken": [{"name": b.name, "source": str(b.source), "error": b.error}
                       for b in registry.broken],
            "conflicts": [c.message() for c in registry.conflicts],
        }
        out(json.dumps(data, indent=2))
        return 0
    if args.knobs:
        return _print_knobs(registry)
    if args.channels:
        return _print_channels(registry)
    header = ("KIND", "NAME", "DISTRIBUTION", "VERSION", "STATUS", "SUMMARY")
    widths = [max(len(str(r[i])) for r in [header, *rows]) for i in range(5)]
    for row in [header, *rows]:
        padded = "  ".join(str(c).ljust(w) for c, w in zip(row[:5], widths, strict=True))
        out(padded + "  " + row[5])
    for broken in registry.broken:
        out(f"broken   {broken.name}  from {broken.source}: {broken.error}")
    for conflict in registry.conflicts:
        out(f"conflict {conflict.message()}")
    if registry.benchmarks:
        out(f"benchmarks: {', '.join(sorted(registry.benchmarks))}")
    return 0


def _print_knobs(registry: Any) -> int:
    """``hapticframe plugins --knobs``: each plugin's declared knobs, then the run loop's."""
    from hapticframe._knobs import RUN_KNOBS, describe_values

    rows = [(f"{reg.spec.kind}/{reg.spec.name}", knob) for reg in registry
            for knob in reg.spec.knobs]
    rows += [("run", knob) for knob in RUN_KNOBS]
    header = ("PLUGIN", "FIELD", "VALUES", "TRADES")
    cells = [(owner, knob.field, describe_values(knob), knob.trades) for owner, knob in rows]
    widths = [max(len(r[i]) for r in [header, *cells]) for i in range(3)]
    for row in [header, *cells]:
        out("  ".join(c.ljust(w) for c, w in zip(row[:3], widths, strict=True)) + "  " + row[3])
    without = sorted(f"{reg.spec.kind}/{reg.spec.name}" for reg in registry if not reg.spec.knobs)
    if without:
        out(f"no knobs: {', '.join(without)}")
    return 0



def _channel_records(channels: Any) -> list[dict[str, Any]]:
    return [{"channel": name, "shape": list(c.shape), "unit": c.unit,
             "description": c.description} for name, c in channels.items()]


def _print_channels(registry: Any) -> int:
    """``hapticframe plugins --channels``: each plugin's channel contract, one line per
    channel it produces (``->``) or consumes (``<-``); ``validate`` holds wiring to them."""
    from hapticframe._contracts import describe_channel

    undeclared = []
    for reg in registry:
        spec = reg.spec
        lines = [f"  <- {describe_channel(n, c)}" for n, c in spec.reads.items()]
        lines += [f"  -> {describe_channel(n, c)}" for n, c in spec.produces.items()]
        if not lines:
            undeclared.append(f"{spec.kind}/{spec.name}")
            continue
        out(f"{spec.kind}/{spec.name}")
        for line in lines:
            out(line)
    if undeclared:
        out("declared when built (channels from a file or a topic): " + ", ".join(undeclared))
    return 0
