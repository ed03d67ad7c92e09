"""Listing, validating and writing schemas never import heavy or device libraries."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

HEAVY = [
    "torch", "sklearn", "serial", "can", "dynamixel_sdk", "matplotlib", "mcap", "newton", "warp",
]
ROOT = Path(__file__).resolve().parents[2]

PROBE = """
import json, sys
from hapticframe.cli._cli import main
try:
    main(sys.argv[1:])
except SystemExit:
    pass
print("\\nMODULES=" + json.dumps(sorted(sys.modules)))
"""


def _modules_after(args: list[str], cwd: Path) -> set[str]:
    proc = subprocess.run([sys.executable, "-c", PROBE, *args], capture_output=True, text=True,
                          cwd=cwd, timeout=300)
    line = [ln for ln in proc.stdout.splitlines() if ln.startswith("MODULES=")][-1]
    return set(json.loads(line[len("MODULES="):]))


@pytest.mark.parametrize(
    "args",
    [
        ["--help"],
        ["plugins"],
        ["schema"],
        ["validate", *sorted(str(p) for p in (ROOT / "examples").glob("*.yaml"))],
    ],
    ids=["help", "plugins", "schema", "validate-examples"],
)
def test_light_commands_import_no_heavy_library(args):
    loaded = _modules_after(args, ROOT)
    assert "hapticframe" in loaded
    leaked = [name for name in HEAVY if name in loaded]
    assert not leaked, f"`hapticframe {' '.join(args[:1])}` imported {leaked}"


def test_loading_every_entry_point_stays_light():
    code = (
        "import sys, json\nfrom hapticframe import make_plugin_manager\n"
        "reg = make_plugin_manager().registry\n"
        "print(json.dumps([len(list(reg)), sorted(sys.modules)]))\n"
    )
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
    count, loaded = json.loads(proc.stdout.strip().splitlines()[-1])
    assert count > 0
    assert not [name for name in HEAVY if name in loaded]
