"""Running the core's commands with the lab-local test plugin module (``labplugin``)."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

from hapticframe._config import validate_file
from hapticframe.cli._cli import main

#: The option that imports the test plugin module (from the current directory).
LAB = ("--plugin-module", "labplugin")


def lab_main(argv: Sequence[str]) -> int:
    """``hapticframe COMMAND --plugin-module labplugin ARGS...``."""
    return main([argv[0], *LAB, *argv[1:]])


def validate_lab(path: str | Path, **kwargs: Any) -> Any:
    """:func:`validate_file` with ``labplugin`` imported from beside ``path``."""
    return validate_file(path, plugin_modules=["labplugin"], plugin_dir=Path(path).parent,
                         **kwargs)
