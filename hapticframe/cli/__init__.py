"""The ``hapticframe`` command: one module per subcommand, on top of every other package."""

from __future__ import annotations

from hapticframe.cli._cli import main

__all__ = ["main"]
