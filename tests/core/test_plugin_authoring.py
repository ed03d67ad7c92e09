"""docs/plugin-authoring.md builds into a real distribution that loads through its entry point."""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys
import zipfile
from itertools import pairwise
from pathlib import Path

import pytest

DOC = Path(__file__).resolve().parents[2] / "docs" / "plugin-authoring.md"
BLOCK = re.compile(r"```\w+ file=(\S+)\n(.*?)```", re.S)


def _write_example(root: Path) -> Path:
    package = root / "hapticframe-loadcell"
    blocks = BLOCK.findall(DOC.read_text(encoding="utf-8"))
    assert len(blocks) >= 6, "the guide lost its file blocks"
    for rel, text in blocks:
        path = package / rel
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text, encoding="utf-8")
    return package


@pytest.fixture(scope="module")
def installed_example(tmp_path_factory) -> dict[str, str]:
    root = tmp_path_factory.mktemp("authoring")
    package = _write_example(root)
    wheels = root / "wheels"
    proc = subprocess.run(
        [sys.executable, "-m", "pip", "wheel", "--no-deps", "--no-build-isolation", "--no-index",
         "-w", str(wheels), str(package)],
        capture_output=True, text=True, timeout=300,
    )
    assert proc.returncode == 0, proc.stdout + proc.stderr
    [wheel] = wheels.glob("hapticframe_loadcell-0.3.0-*.whl")
    site = root / "site"
    with zipfile.ZipFile(wheel) as archive:  # "installing" a pure wheel = unpacking it
        archive.extractall(site)
    pythonpath = os.pathsep.join([str(site), os.environ.get("PYTHONPATH", "")])
    env = dict(os.environ, PYTHONPATH=pythonpath)
    env.pop("HAPTICFRAME_DISABLE_PLUGIN_AUTOLOAD", None)
    return env


def _hapticframe(
    env: dict[str, str], *args: str, cwd: Path | None = None
) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "hapticframe", *args], capture_output=True,
                          text=True, env=env, cwd=cwd, timeout=600)


def test_the_example_registers_through_its_entry_point(installed_example):
    proc = _hapticframe(installed_example, "plugins", "--json")
    assert proc.returncode == 0, proc.stderr
    rows = {(p["kind"], p["name"]): p for p in json.loads(proc.stdout)["plugins"]}
    row = rows[("sensor", "lab-load-cell")]
    assert row["distribution"] == "hapticframe-loadcell" and row["version"] == "0.3.0"
    assert row["status"] == "ok"


def test_the_example_passes_the_conformance_kit(installed_example):
    proc = _hapticframe(installed_example, "check", "lab-load-cell")
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert "all checks passed" in proc.stdout


def test_the_example_experiment_validates(installed_example, tmp_path):
    (tmp_path / "e.yaml").write_text(
        "schema_version: 1\nname: load-cell\nseed: 1\nsensors:\n"
        "  - {id: wrist, type: lab-load-cell, config: {transport: emulator, rate_hz: 200}}\n"
    )
    proc = _hapticframe(installed_example, "validate", "e.yaml", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr


def test_the_examples_own_test_file_runs_under_pytest(installed_example, tmp_path):
    package = _write_example(tmp_path)
    command = [sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider",
               str(package / "tests")]
    proc = subprocess.run(command, capture_output=True, text=True, env=installed_example,
                          cwd=tmp_path, timeout=600)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert "passed" in proc.stdout


def test_the_example_benchmark_runs_and_refuses_bad_options(installed_example, tmp_path):
    out = tmp_path / "bench"
    proc = _hapticframe(installed_example, "bench", "lab-load-cell", "--trials", "20",
                        "--out", str(out))
    assert proc.returncode == 0, proc.stderr
    report = json.loads((out / "lab-load-cell.json").read_text())
    assert sorted(report, key=int) == ["1", "5", "20"]
    for size, row in report.items():
        assert row["reads"] == 20 and row["median_read_us"] > 0
        assert row["median_per_sample_us"] == pytest.approx(row["median_read_us"] / int(size))
    assert "samples per read" in proc.stdout
    proc = _hapticframe(installed_example, "bench", "lab-load-cell", "--trials", "3",
                        "--out", str(out))
    assert proc.returncode == 2
    assert "at least 10 reads" in proc.stderr and "Traceback" not in proc.stderr


SERIAL_SESSION = """
import json
import numpy as np
from hapticframe.kinds import BuildContext
from hf_loadcell.config import LoadCellConfig
from hf_loadcell.sensor import LoadCellSensor

config = LoadCellConfig(transport="serial", port="loop://", samples_per_read=4)
sensor = LoadCellSensor(config, BuildContext("cell", np.random.default_rng(0)))
link = sensor.transport.link
reads = {"timeout": link.timeout, "idle": len(sensor.read())}
link.write(b"2148\\n#garbage\\xff\\nnan\\n2048\\n1948\\n20")
first = sensor.read()
link.write(b"48\\n" + b"x" * 100)
second = sensor.read()
reads.update(
    first=first.channels["force_n"][:, 0].tolist(),
    second=second.channels["force_n"][:, 0].tolist(),
    times=np.concatenate([first.timestamps_s, second.timestamps_s]).tolist(),
    garbage=sensor.transport.garbage_lines,
)
sensor.close()
reads["closed"] = not link.is_open
print(json.dumps(reads))
"""


def test_the_serial_transport_skips_garbage_and_never_waits(installed_example):
    # pyserial's loop:// port reads back what is written: a device that sends a reading, a
    # line of noise, a NaN, two readings and half a line, then the rest of that line and
    # 100 bytes without a newline.
    pytest.importorskip("serial")
    proc = subprocess.run([sys.executable, "-c", SERIAL_SESSION], capture_output=True, text=True,
                          env=installed_example, timeout=120, check=False)
    assert proc.returncode == 0, proc.stderr
    reads = json.loads(proc.stdout)
    assert reads["timeout"] == 0 and reads["idle"] == 0  # no data: an empty batch at once
    assert reads["first"] == pytest.approx([1.0, 0.0, -1.0])
    assert reads["second"] == pytest.approx([0.0])  # the half line, completed
    assert reads["garbage"] == 3  # "#garbage", "nan" and the 100 bytes without a newline
    assert all(b > a for a, b in pairwise(reads["times"]))
    assert reads["closed"]
