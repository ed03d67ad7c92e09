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
        "  - {id: wrist, type: lab-load-cell, config: {port: emulated, rate_hz: 200}}\n"
        "run: {duration_s: 5}\n"
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


EMULATED_SESSION = """
import json
import numpy as np
from hapticframe.devices import LifecycleState
from hapticframe.kinds import BuildContext, RunClock
from hf_loadcell.config import LoadCellConfig
from hf_loadcell.sensor import LoadCellSensor

faults = [{"kind": "garbage", "at_s": 0.2, "params": {"count": 40}},
          {"kind": "fragment", "at_s": 0.0, "duration_s": 1.0},
          {"kind": "stall", "at_s": 1.2, "duration_s": 0.3, "params": {"drop": 1}},
          {"kind": "disconnect", "at_s": 2.0, "duration_s": 0.2}]
config = LoadCellConfig(faults=faults)
clock = RunClock(0.02)  # a control period of two samples
sensor = LoadCellSensor(config, BuildContext("cell", np.random.default_rng(3), clock=clock))
sensor.configure()
sensor.activate()
batches = []
for _ in range(200):  # 4 s of the run's clock
    clock.advance()
    batches.append(sensor.read())
model = sensor.emulator.model
counts = np.concatenate([b.channels["force_n"][:, 0] for b in batches]) / 0.01 + 2048
times = np.concatenate([b.timestamps_s for b in batches])
sent = iter(model.sent)
report = {
    # A stable link (as /dev/serial/by-id/...) to the pty that pyserial opened.
    "path": __import__("os").path.realpath(sensor.emulator.path),
    "live": sensor.live,
    "state": sensor.lifecycle_state.name,
    "delivered": len(counts),
    "sent": len(model.sent),
    "subsequence": all(any(c == round(x) for c in sent) for x in counts),
    "increasing": bool(np.all(np.diff(times) > 0)),
    "time_span": [float(times[0]), float(times[-1]), sensor.clock.now()],
    "health": sensor.health.as_dict(),
    "injected": sorted({f.kind for f in sensor.emulator.faults.injected}),
}
sensor.close()
report["closed"] = sensor.lifecycle_state.name
print(json.dumps(report))
"""


def test_the_driver_runs_against_its_pty_emulator_with_faults(installed_example):
    # The guide's driver opens the emulator's pseudo-terminal through pyserial, while the
    # emulator inserts 40 bytes of noise, fragments writes for a second, swallows 0.3 s of
    # data and unplugs the device for 0.2 s.
    pytest.importorskip("serial")
    proc = subprocess.run([sys.executable, "-c", EMULATED_SESSION], capture_output=True,
                          text=True, env=installed_example, timeout=120, check=False)
    assert proc.returncode == 0, proc.stderr
    report = json.loads(proc.stdout)
    assert report["path"].startswith("/dev/") and not report["live"]
    assert report["state"] == "ACTIVE" and report["closed"] == "FINALIZED"
    assert report["injected"] == ["disconnect", "fragment", "garbage", "stall"]
    assert report["subsequence"] and report["increasing"]  # nothing corrupted, time runs on
    health = report["health"]
    # 400 samples in 4 s; the stall drops ~30 and the unplugged 0.2 s (plus the reopen) more.
    assert 300 <= report["delivered"] <= report["sent"] <= 400
    assert health["frames"] == report["delivered"]
    assert health["crc_errors"] + health["overflows"] >= 1  # the noise, caught
    assert health["dropped_samples"] >= 25  # the stall's gap in the sequence numbers
    assert health["reconnects"] == 1 and health["recoveries"] == 1
    start, end, now = report["time_span"]
    # 200 reads of 20 ms of the run's clock, which the emulator follows: recovery's backoff
    # (slept on the fake clock) is caught up with, not added.
    assert 0 <= start < 0.1 and 3.8 < end <= now and 4.0 <= now <= 4.0 + 0.05 + 0.1 + 0.2


LIVE_SESSION = """
import json
import numpy as np
from hapticframe.kinds import BuildContext
from hf_loadcell.config import LoadCellConfig
from hf_loadcell.sensor import LoadCellSensor, encode

config = LoadCellConfig(port="loop://")
sensor = LoadCellSensor(config, BuildContext("cell", np.random.default_rng(0)))
sensor.configure()
sensor.activate()
idle = len(sensor.read())
port = sensor.transport.port
port.write(encode(0, 2148) + b"#noise\\n" + encode(1, 2048)[:-3] + b"X\\n" + encode(2, 1948))
first = sensor.read()
port.write(encode(3, 2048)[:4])
port.write(encode(3, 2048)[4:])
second = sensor.read()
print(json.dumps({
    "idle": idle, "live": sensor.live, "timeout": port.timeout,
    "first": first.channels["force_n"][:, 0].tolist(),
    "second": second.channels["force_n"][:, 0].tolist(),
    "times": np.concatenate([first.timestamps_s, second.timestamps_s]).tolist(),
    "health": sensor.health.as_dict(),
}))
sensor.close()
"""


def test_the_driver_reads_a_real_port_without_waiting(installed_example):
    # pyserial's loop:// port reads back what is written: the real-port path (monotonic
    # clock, wall-clock pacing) fed two good lines around a noise line and a corrupted one.
    pytest.importorskip("serial")
    proc = subprocess.run([sys.executable, "-c", LIVE_SESSION], capture_output=True, text=True,
                          env=installed_example, timeout=120, check=False)
    assert proc.returncode == 0, proc.stderr
    reads = json.loads(proc.stdout)
    assert reads["idle"] == 0 and reads["timeout"] == 0 and reads["live"]
    assert reads["first"] == pytest.approx([1.0, -1.0])
    assert reads["second"] == pytest.approx([0.0])  # a line split across two writes
    health = reads["health"]
    assert health["crc_errors"] == 2 and health["dropped_samples"] == 1  # seq 1 never came
    assert all(b > a for a, b in pairwise(reads["times"]))
