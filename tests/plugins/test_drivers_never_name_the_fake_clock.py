"""Emulation stays out of the drivers: a driver is handed a port (its link and clock) and never
asks whether it is emulated. Only the emulator modules (``_emulator*``) and the port or bus
modules that pace an emulated link (``_bus*``) may name the fake clock."""

from __future__ import annotations

import re
from pathlib import Path

PLUGINS = Path(__file__).resolve().parents[2] / "plugins"
ALLOWED = re.compile(r"^_(emulator|bus)\w*\.py$")


def modules_naming_the_fake_clock(root: Path) -> list[str]:
    """The plugin modules outside the emulator and bus modules that mention ``FakeClock``."""
    return sorted(
        str(path.relative_to(root))
        for path in root.rglob("*.py")
        if not ALLOWED.match(path.name) and "FakeClock" in path.read_text(encoding="utf-8")
    )


def test_no_driver_names_the_fake_clock() -> None:
    assert any(PLUGINS.glob("hapticframe_*/_emulator*.py"))  # the rule looks at real plugins
    assert modules_naming_the_fake_clock(PLUGINS) == []


def test_the_rule_finds_a_driver_that_names_it(tmp_path: Path) -> None:
    plugin = tmp_path / "hapticframe_lab"
    plugin.mkdir()
    (plugin / "_emulator.py").write_text("from hapticframe.devices import FakeClock\n")
    (plugin / "_bus_pty.py").write_text("clock = FakeClock(0.0)\n")
    (plugin / "_robot.py").write_text("if isinstance(clock, FakeClock):\n    pass\n")
    (plugin / "plugin.py").write_text("import hapticframe\n")
    assert modules_naming_the_fake_clock(tmp_path) == ["hapticframe_lab/_robot.py"]
