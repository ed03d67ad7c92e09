"""Issue 26 §6: pulling the FT 300's port mid-movement halts the emulated rig in time.

The FT 300 of the device-chain example (a sandbox arm, an FT 300 and a BNO055 behind
pseudo-terminals, in simulation time) is unplugged for good during the first movement. The
driver's reads never wait while it recovers, so the loop's stall check sees the silent force
stream and halts the arm within ``run.force_stall_s`` plus one control period of the pull,
measured on the simulation's clock (the robot's state timestamps); only after the bounded
recovery gives up does the run end with the device error (exit 1). Before, one read
blocked through the whole recovery (in the simulation: the device's clock ran seconds
ahead while the arm stood still) and the run failed with no stall halt.
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest
import yaml

from hapticframe.cli._cli import main

pytest.importorskip("serial")
pytest.importorskip("hapticframe_robotiq")

EXAMPLE = Path(__file__).resolve().parents[2] / "examples" / "search-ellipse-ft300.yaml"
PULLED_AT_S = 1.0


def test_pulling_the_ft300_port_mid_movement_halts_the_rig_within_the_stall_time(tmp_path):
    data = yaml.safe_load(EXAMPLE.read_text())
    wrist = next(s for s in data["sensors"] if s["id"] == "wrist")
    wrist["config"]["faults"] = [{"kind": "disconnect", "at_s": PULLED_AT_S,
                                  "duration_s": 1000.0}]
    data["run"].update({"force_stall_s": 0.25, "stall_resumes": 0, "max_movements": 2})
    path = tmp_path / "pulled.yaml"
    path.write_text(yaml.safe_dump(data))
    code = main(["run", str(path), "--out", str(tmp_path / "out"), "--quiet"])
    run = json.loads((tmp_path / "out" / "run.json").read_text())
    halts = run["details"].get("safety_halts", [])
    assert halts, run
    first = halts[0]
    assert first["reason"] == "force_stream_stalled"
    rate_hz = 100.0  # the sandbox's control rate
    # The last sample before the pull arrived at most one frame period before it.
    assert PULLED_AT_S - 0.02 <= first["robot_time_s"] - first["silent_s"] <= PULLED_AT_S
    assert first["robot_time_s"] - PULLED_AT_S <= 0.25 + 1.0 / rate_hz + 1e-9
    # The sensor never came back: the next movement is halted for the silent stream too,
    # 0.25 s after it began (or the run ended with the device error after the halt).
    assert code == 1 or [h["reason"] for h in halts] == ["force_stream_stalled"] * 2


def test_a_read_on_a_live_port_never_waits_while_the_sensor_recovers():
    """A live host (its clock moved by the test, as wall time passes between reads): the
    port is pulled at 1.0 s and comes back at 1.3 s. Every read returns without letting any
    time pass — before, one read slept through the whole reconnect backoff — and the sensor
    streams again after the replug."""
    import numpy as np

    from hapticframe.devices import EmulatedTransport, FakeClock, FaultSchedule, LinkPort
    from hapticframe.kinds import BuildContext
    from hapticframe_robotiq._config import Ft300Config
    from hapticframe_robotiq._emulator import Ft300Model
    from hapticframe_robotiq._sensor import Ft300Sensor

    clock = FakeClock(0.0)
    schedule = FaultSchedule.from_config(
        [{"kind": "disconnect", "at_s": 1.0, "duration_s": 0.3}], np.random.default_rng(7))
    model = Ft300Model(rng=np.random.default_rng(8), faults=schedule)
    port = LinkPort(EmulatedTransport(model, clock, schedule), clock, "usb-ft300")
    sensor = Ft300Sensor(Ft300Config(port="usb-ft300", tare_s=0.0),
                         BuildContext(id="wrist", rng=np.random.default_rng(9)), port=port)
    sensor.configure()
    sensor.activate()  # the handshake before the loop may wait: it sleeps the clock
    delivered_after_replug = 0
    try:
        while clock.now() < 3.0:
            clock.advance(0.01)  # one control period of wall time between reads
            before = clock.now()
            batch = sensor.read()
            assert clock.now() == before, "a read waited"
            if before > 1.3:
                delivered_after_replug += len(batch)
        assert sensor.health.reconnects == 1 and sensor.health.recoveries >= 1
        assert delivered_after_replug > 100
    finally:
        sensor.close()
