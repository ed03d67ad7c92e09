"""The FT 300 driver against every fault of its emulator's matrix (in-process, FakeClock).

For each fault: the driver survives, recovers within its watchdog bounds in device time,
the health counter the fault should raise is non-zero, and every sample it delivers as
valid is a frame the device sent intact (no corrupted frame is ever delivered as valid).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import pytest

from hapticframe.devices import (
    DeviceError,
    EmulatedTransport,
    FakeClock,
    FaultSchedule,
    LifecycleState,
)
from hapticframe.kinds import BuildContext, SampleBatch, concatenate_batches
from hapticframe_robotiq._config import Ft300Config
from hapticframe_robotiq._emulator import Ft300Model, Ft300Physics
from hapticframe_robotiq._protocol import quantise
from hapticframe_robotiq._sensor import Ft300Sensor

#: Longest gap between delivered samples when the driver has to recover from a silent
#: stream: the frame watchdog (0.16 s), a jam (0xFF burst, 0.08 s of silence, 0.1 s
#: settling), the start request and the first frame, with a margin.
RECOVERY_GAP_S = 0.16 + 0.08 + 0.1 + 0.1


@dataclass
class Run:
    sensor: Ft300Sensor
    model: Ft300Model
    schedule: FaultSchedule
    clock: FakeClock
    batches: list[SampleBatch] = field(default_factory=list)

    @property
    def batch(self) -> SampleBatch:
        return concatenate_batches([b for b in self.batches if len(b)])


def _start(faults: list[dict[str, Any]], **config: Any) -> Run:
    clock = FakeClock(0.0)
    schedule = FaultSchedule.from_config(faults, np.random.default_rng(7))
    model = Ft300Model(
        rng=np.random.default_rng(8),
        faults=schedule,
        physics=Ft300Physics(noise_std_n=0.1, noise_std_nm=0.003, offset_n=(0.5, -0.2, 1.0)),
    )
    transport = EmulatedTransport(model, clock, schedule)
    sensor = Ft300Sensor(
        Ft300Config(port="link-under-test", **config),
        BuildContext(id="wrist", rng=np.random.default_rng(9)),
        transport=transport,
        clock=clock,
    )
    return Run(sensor, model, schedule, clock)


def _run(faults: list[dict[str, Any]], seconds: float = 3.0, **config: Any) -> Run:
    run = _start(faults, **config)
    run.sensor.configure()
    run.sensor.activate()
    for _ in range(round(seconds / 0.01)):
        run.batches.append(run.sensor.read())
    return run


def _delivered_counts(run: Run, batch: SampleBatch) -> list[tuple[int, ...]]:
    force_offset, torque_offset = run.sensor.offsets
    force = batch.channels["force_n"] + force_offset
    torque = batch.channels["torque_nm"] + torque_offset
    return [quantise(f, m) for f, m in zip(force, torque, strict=True)]


def _assert_only_intact_frames(run: Run) -> SampleBatch:
    """Every valid sample is, in order, a frame the device sent intact."""
    batch = run.batch
    valid = batch.valid["force_n"] & batch.valid["torque_nm"]
    delivered = _delivered_counts(run, batch.select(valid))
    intact = [quantise(f.force_n, f.torque_nm) for f in run.model.sent if f.intact]
    position = 0
    for k, counts in enumerate(delivered):
        while position < len(intact) and intact[position] != counts:
            position += 1
        assert position < len(intact), f"valid sample {k} {counts} was never sent intact"
        position += 1
    corrupted = [quantise(f.force_n, f.torque_nm) for f in run.model.sent if not f.intact]
    assert corrupted or not run.schedule.count("bad_crc")
    return batch


def _max_gap(batch: SampleBatch) -> float:
    return float(np.max(np.diff(batch.timestamps_s)))


def _really_lost(run: Run, batch: SampleBatch) -> int:
    """Frames the device sent from the first delivered one on that were never delivered."""
    delivered = set(_delivered_counts(run, batch))
    first = batch.timestamps_s[0] - 1e-9
    return sum(1 for f in run.model.sent
               if f.time_s >= first and quantise(f.force_n, f.torque_nm) not in delivered)


def _sent_faulty(run: Run, fault: str) -> int:
    return sum(1 for f in run.model.sent if f.fault == fault)


@dataclass(frozen=True)
class Case:
    faults: list[dict[str, Any]]
    check: Callable[[Run], None]
    max_gap_s: float = 0.035  # a lost frame or two, no recovery


def _counter(name: str, minimum: int = 1) -> Callable[[Run], None]:
    def check(run: Run) -> None:
        assert run.sensor.health.as_dict()[name] >= minimum, run.sensor.health.as_dict()

    return check


def _all(*checks: Callable[[Run], None]) -> Callable[[Run], None]:
    def check(run: Run) -> None:
        for one in checks:
            one(run)

    return check


def _no_recovery(run: Run) -> None:
    assert run.sensor.health.recoveries == 0, run.sensor.health.as_dict()


def _jams(n: int) -> Callable[[Run], None]:
    def check(run: Run) -> None:
        assert run.model.stats["jams"] >= n, run.model.stats

    return check


def _modbus(cause: str) -> Callable[[Run], None]:
    def check(run: Run) -> None:
        assert run.sensor.modbus_errors[cause] >= 1, run.sensor.modbus_errors

    return check


def _invalid_where(fault: str) -> Callable[[Run], None]:
    def check(run: Run) -> None:
        batch = run.batch
        valid = batch.valid["force_n"] & batch.valid["torque_nm"]
        assert (~valid).sum() >= 1
        assert run.sensor.health.invalid_samples == (~valid).sum()
        assert _sent_faulty(run, fault) >= 1

    return check


def _header_frames_delivered(run: Run) -> None:
    batch = run.batch
    delivered = set(_delivered_counts(run, batch))
    sent = [quantise(f.force_n, f.torque_nm) for f in run.model.sent
            if f.fault == "header_in_payload"]
    assert sent and all(counts in delivered for counts in sent)
    assert run.sensor.health.crc_errors == 0  # never lost sync


def _stall_only(run: Run) -> None:
    assert run.sensor.health.stalls == 0 and run.sensor.health.recoveries == 0


CASES: dict[str, Case] = {
    "boots_streaming": Case(
        [{"kind": "boots_streaming", "at_s": 0.0}],
        _all(_jams(1), lambda run: run.sensor.device_info is not None),
    ),
    "partial_jam": Case(
        [{"kind": "boots_streaming", "at_s": 0.0}, {"kind": "partial_jam", "at_s": 0.0}],
        _all(_jams(1), lambda run: run.model.stats["ignored_jams"] == 1),
    ),
    "bad_crc": Case([{"kind": "bad_crc", "rate_hz": 3.0}], _counter("crc_errors")),
    "frame_drop_bytes": Case(
        [{"kind": "frame_drop_bytes", "rate_hz": 3.0, "params": {"count": 2}}],
        _all(_counter("crc_errors"), _counter("resyncs")),
    ),
    "header_in_payload_fx": Case(
        [{"kind": "header_in_payload", "rate_hz": 5.0, "params": {"offset": 0}}],
        _header_frames_delivered,
    ),
    "header_in_payload_edge": Case(
        [{"kind": "header_in_payload", "rate_hz": 5.0, "params": {"offset": 3}}],
        _header_frames_delivered,
    ),
    "garbage": Case(
        [{"kind": "garbage", "rate_hz": 3.0, "params": {"count": 7}}],
        _all(_counter("resyncs"), _no_recovery),
    ),
    "drop_bytes": Case(
        [{"kind": "drop_bytes", "rate_hz": 3.0, "params": {"count": 3}}],
        _all(_counter("crc_errors"), _no_recovery),
    ),
    "fragment": Case(
        [{"kind": "fragment", "at_s": 0.5, "duration_s": 2.0}], _all(_no_recovery, _stall_only)
    ),
    "stall_50ms": Case(
        [{"kind": "stall", "at_s": 1.0, "duration_s": 0.05}], _stall_only, max_gap_s=0.065
    ),
    "stall_100ms": Case(
        [{"kind": "stall", "at_s": 1.0, "duration_s": 0.1}],
        _all(_counter("stalls"), _no_recovery),
        max_gap_s=0.115,
    ),
    "stall_200ms": Case(
        [{"kind": "stall", "at_s": 1.0, "duration_s": 0.2}],
        _all(_counter("stalls"), _counter("timeouts"), _counter("recoveries"), _jams(1),
             _counter("dropped_samples", 10)),
        max_gap_s=RECOVERY_GAP_S + 0.05,
    ),
    "stream_stop": Case(
        # A stream that stops sends nothing more: no frame of it is missing.
        [{"kind": "stream_stop", "at_s": 1.0}],
        _all(_counter("stalls"), _counter("recoveries"), _jams(1)),
        max_gap_s=RECOVERY_GAP_S,
    ),
    "saturation": Case(
        [{"kind": "saturation", "at_s": 1.0, "duration_s": 0.1}], _invalid_where("saturation")
    ),
    "frozen": Case(
        [{"kind": "frozen", "at_s": 1.0, "duration_s": 1.0}], _invalid_where("frozen")
    ),
    "offset_drift": Case(
        [{"kind": "offset_drift", "at_s": 1.0, "duration_s": 1.0,
          "params": {"rate_n_per_s": 4.0}}],
        lambda run: run.model.sent[-1].force_n[0] > 3.9,
    ),
    "no_reply": Case([{"kind": "no_reply", "at_s": 0.0}], _all(_counter("timeouts"),
                                                                _modbus("timeout"))),
    "modbus_bad_crc": Case([{"kind": "modbus_bad_crc", "at_s": 0.0}], _modbus("crc")),
    "wrong_slave": Case([{"kind": "wrong_slave", "at_s": 0.0}], _modbus("wrong_reply")),
    "exception_reply": Case([{"kind": "exception_reply", "at_s": 0.0}], _modbus("exception")),
    "missing_echo": Case(
        [{"kind": "missing_echo", "at_s": 0.0}], _all(_counter("timeouts"), _modbus("timeout"))
    ),
    "disconnect": Case(
        [{"kind": "disconnect", "at_s": 1.0, "duration_s": 0.2}],
        # Unplugged, the device sends nothing: no frame of a stream is missing.
        _all(_counter("reconnects"), _counter("recoveries")),
        max_gap_s=0.2 + 0.05 + 0.1 + 0.2 + RECOVERY_GAP_S,
    ),
}


@pytest.mark.parametrize("name", sorted(CASES))
def test_the_driver_survives_each_fault(name):
    case = CASES[name]
    run = _run(case.faults)
    kinds = {entry["kind"] for entry in case.faults}
    assert all(run.schedule.count(kind) >= 1 for kind in kinds), run.schedule.injected
    assert run.sensor.lifecycle_state is LifecycleState.ACTIVE
    batch = _assert_only_intact_frames(run)
    case.check(run)
    # dropped_samples counts the frames missing from the stream's own sequence: those the
    # device sent after the first delivered one and that never arrived, no more, no fewer.
    assert run.sensor.health.dropped_samples == _really_lost(run, batch)
    assert len(batch) >= 0.8 * 300
    assert _max_gap(batch) <= case.max_gap_s, (_max_gap(batch), run.sensor.health.as_dict())
    # Still streaming at the end: the last read delivered fresh samples.
    assert len(run.batches[-1]) >= 1
    run.sensor.close()
    assert run.sensor.lifecycle_state is LifecycleState.FINALIZED


def test_a_clean_run_delivers_every_frame_once():
    run = _run([], seconds=2.0)
    batch = _assert_only_intact_frames(run)
    health = run.sensor.health
    assert health.faults() == {}
    assert health.frames >= len(batch)
    # Every frame sent after activation was delivered, in order, one period apart.
    np.testing.assert_allclose(np.diff(batch.timestamps_s), 0.01, atol=0.0041)
    assert run.sensor.device_info.firmware == "FTS-3.0.1"


def test_the_tare_zeroes_the_offset_and_a_requested_tare_removes_a_drift():
    run = _run([{"kind": "offset_drift", "at_s": 1.0, "duration_s": 0.5,
                 "params": {"rate_n_per_s": 4.0}}], seconds=2.0)
    force_offset, _ = run.sensor.offsets
    np.testing.assert_allclose(force_offset, [0.5, -0.2, 1.0], atol=0.05)
    late = run.batches[-1].channels["force_n"]
    assert late[-1, 0] == pytest.approx(2.0, abs=0.4)  # 0.5 s at 4 N/s
    run.sensor.tare()
    assert run.sensor.tare_pending
    for _ in range(40):
        run.batches.append(run.sensor.read())
    assert not run.sensor.tare_pending
    recent = concatenate_batches(run.batches[-10:]).channels["force_n"]
    assert abs(recent[:, 0].mean()) < 0.1


def _read_until_error(run: Run) -> None:
    run.sensor.configure()
    run.sensor.activate()
    for _ in range(1000):
        run.sensor.read()


def test_a_device_that_never_comes_back_raises_device_error_in_bounded_time():
    run = _start([{"kind": "dead", "at_s": 1.0}])
    with pytest.raises(DeviceError, match="did not recover") as info:
        _read_until_error(run)
    assert "wrist" in str(info.value)
    # Watchdog + 3 recoveries, each a bounded jam (5 bursts × 0.5 s listening).
    assert run.clock.now() < 1.0 + 0.2 + 3 * (5 * 0.51 + 0.2)
    assert run.sensor.health.recoveries == 3
    assert run.sensor.lifecycle_state is LifecycleState.ERROR
    run.sensor.close()


def test_a_port_that_never_reopens_fails_after_the_backoff():
    run = _start([{"kind": "disconnect", "at_s": 1.0, "duration_s": 1000.0}])
    with pytest.raises(DeviceError):
        _read_until_error(run)
    assert run.sensor.health.reconnects == 0
    assert run.clock.now() < 1.0 + 3 * 2.0


def test_configure_fails_cleanly_when_nothing_answers():
    run = _start([{"kind": "dead", "at_s": 0.0}])
    with pytest.raises(DeviceError, match="configure"):
        run.sensor.configure()
    assert run.sensor.lifecycle_state is LifecycleState.ERROR
    assert run.clock.now() < 5 * 0.51 + 0.1
