"""``hapticframe check``: run the conformance kit on installed plugins."""

from __future__ import annotations

import argparse
import time
from typing import Any

from hapticframe.cli._common import (
    add_plugin_module_option,
    out,
    plugin_manager,
)

__all__ = ["register"]


def register(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Add ``hapticframe check`` to the command line."""
    p = sub.add_parser("check", help="run the conformance kit on installed plugins")
    p.add_argument("names", nargs="+", metavar="NAME")
    p.add_argument("--kind", choices=[k.value for k in _kinds()], help="only plugins of this kind")
    add_plugin_module_option(p)
    p.set_defaults(func=cmd_check)


def cmd_check(args: argparse.Namespace) -> int:
    from hapticframe._errors import UsageError
    from hapticframe._kind import Kind
    from hapticframe.testing import checks_for, iter_checks

    registry = plugin_manager(args).registry
    selected = []
    for name in args.names:
        found = registry.find(name)
        if args.kind:
            found = [r for r in found if r.spec.kind is Kind(args.kind)]
        if not found:
            if args.kind:
                raise UsageError(registry.unknown_message(Kind(args.kind), name))
            raise UsageError(_unknown_plugin_message(registry, name))
        selected.extend(found)
    failures = 0
    for number, reg in enumerate(selected, 1):
        # A robot's checks drive whole movements (seconds each): say what runs before it does.
        names = checks_for(reg.spec)
        out(f"[{number}/{len(selected)}] {reg.spec.kind}/{reg.spec.name}: {len(names)} checks")
        started = time.perf_counter()
        for result in iter_checks(reg.spec, registry=registry):
            message = f"  {result.message}" if result.message and result.status != "PASS" else ""
            out(f"{result.status:<5} {reg.spec.kind}/{reg.spec.name}::{result.check}"
                f"  ({time.perf_counter() - started:.1f} s){message}")
            started = time.perf_counter()
            failures += result.status in ("FAIL", "XPASS")
    out(f"{failures} check(s) failed" if failures else "all checks passed")
    return 1 if failures else 0


def _unknown_plugin_message(registry: Any, name: str) -> str:
    """No plugin of any kind is called ``name``: say so, with close names."""
    import difflib

    names = sorted({reg.spec.name for reg in registry})
    close = difflib.get_close_matches(name, names, n=3, cutoff=0.5)
    hint = f"; did you mean {' or '.join(repr(c) for c in close)}?" if close else ""
    return f"no plugin called {name!r} is installed{hint} (see `hapticframe plugins`)"


def _kinds() -> list[Any]:
    from hapticframe._kind import Kind

    return list(Kind)

