"""The device plugins against real hardware.

Skipped unless pytest runs with ``--hardware``; each test also needs its device's port in an
environment variable (a device path such as ``/dev/serial/by-id/usb-FTDI_...-port0``, or
any pyserial URL)::

    HAPTICFRAME_FT300_PORT=/dev/ttyUSB0 HAPTICFRAME_BNO055_PORT=/dev/ttyUSB1 \\
        python -m pytest --hardware tests/hardware

Keep the devices still while these run: the FT 300 test tares and expects a quiet reading,
the BNO055 test expects gravity.
"""

from __future__ import annotations

import json
import math
import os
import time
from pathlib import Path

import numpy as np
import pytest
import yaml

from hapticframe import Kind, get_registry
from hapticframe.cli._cli import main
from hapticframe.kinds import SampleBatch, Sensor, concatenate_batches
from hapticframe.testing import make_component, release_component

pytestmark = pytest.mark.hardware

ROOT = Path(__file__).resolve().parents[2]


def _port(variable: str) -> str:
    port = os.environ.get(variable)
    if not port:
        pytest.skip(f"set {variable} to the device's port")
    return port


def _stream(sensor: Sensor, seconds: float) -> SampleBatch:
    """What the sensor delivers over ``seconds`` of wall time, read every 10 ms as a run does."""
    batches = []
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        batches.append(sensor.read())
        time.sleep(0.01)
    batch = concatenate_batches([b for b in batches if len(b)])
    assert len(batch) > 1, "the device delivered no samples"
    return batch


def _build(name: str, config: dict[str, object]) -> Sensor:
    spec = get_registry().plugins[Kind.SENSOR][name].spec
    return make_component(spec, config=config, scene=None, interface=Sensor)


def test_ft300_streams_tared_forces_at_100_hz():
    sensor = _build("robotiq-ft300", {"port": _port("HAPTICFRAME_FT300_PORT"), "tare_s": 0.5})
    try:
        assert sensor.live
        batch = _stream(sensor, 3.0)
        t = batch.timestamps_s
        rate = (len(t) - 1) / (t[-1] - t[0])
        assert 90.0 < rate < 110.0, f"{rate:.1f} Hz"
        valid = batch.valid.get("force_n", np.ones(len(batch), bool))
        assert valid.mean() > 0.95
        force = batch.channels["force_n"][valid]
        assert np.isfinite(force).all()
        # Tared at rest: what remains is the sensor's noise (its resolution is 0.01 N).
        assert np.abs(force.mean(axis=0)).max() < 1.0
        health = sensor.health.as_dict()  # type: ignore[attr-defined]
        assert health["frames"] >= len(batch)
        assert health["crc_errors"] <= 0.01 * health["frames"]
    finally:
        release_component(sensor)


def test_bno055_reads_gravity_at_rest():
    sensor = _build("bno055", {"port": _port("HAPTICFRAME_BNO055_PORT"), "mode": "ndof"})
    try:
        assert sensor.live
        batch = _stream(sensor, 3.0)
        ok = batch.valid.get("acceleration_m_per_s2", np.ones(len(batch), bool))
        assert ok.mean() > 0.9
        acceleration = batch.channels["acceleration_m_per_s2"][ok]
        magnitude = float(np.linalg.norm(acceleration.mean(axis=0)))
        assert math.isclose(magnitude, 9.81, abs_tol=0.5), magnitude
        turning = batch.channels["angular_velocity_rad_per_s"][ok]
        assert np.abs(turning.mean(axis=0)).max() < 0.05
    finally:
        release_component(sensor)


def test_the_search_example_runs_on_real_ports(tmp_path):
    """examples/search-ellipse-ft300.yaml with its two port lines changed, and nothing else
    but a one-movement limit (the robot is still the simulated sandbox)."""
    data = yaml.safe_load((ROOT / "examples" / "search-ellipse-ft300.yaml").read_text())
    ports = {"wrist": _port("HAPTICFRAME_FT300_PORT"), "imu": _port("HAPTICFRAME_BNO055_PORT")}
    for sensor in data["sensors"]:
        sensor["config"]["port"] = ports[sensor["id"]]
    data.setdefault("run", {})["max_movements"] = 1
    experiment = tmp_path / "real-ports.yaml"
    experiment.write_text(yaml.safe_dump(data))
    assert main(["run", str(experiment), "--out", str(tmp_path / "run"), "--quiet"]) == 0
    metrics = json.loads((tmp_path / "run" / "metrics.json").read_text())
    assert set(metrics["devices"]) == {"wrist", "imu"}
    assert metrics["devices"]["wrist"]["frames"] > 0
