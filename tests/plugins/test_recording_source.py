"""The ``recording`` sensor: a sensor channel of a ``run.mcap`` fed into a pipeline again."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import hapticframe_recording._mcap as mcap_sensor
from hapticframe.kinds import SampleBatch
from hapticframe.record._recording import RECORDING, RunRecording
from hapticframe.testing import make_component, run_checks
from hapticframe_recording.plugin import SPECS

SPEC = next(s for s in SPECS if s.name == "recording")


def _write(directory: Path, blocks: int = 3, per_block: int = 20) -> SampleBatch:
    """A recording of sensor 'wrist' (a 2-D force with a NaN and an invalid sample, and a
    scalar) as a run writes it; the samples it holds."""
    directory.mkdir(parents=True, exist_ok=True)
    recording = RunRecording(directory / RECORDING, block_s=0.05)
    batches = []
    for k in range(blocks):
        t = (np.arange(per_block) + per_block * k) / 250.0
        force = np.column_stack([np.sin(t), np.cos(t)]) * 3.0
        if k == 1:
            force[2, 0] = np.nan
        valid = np.ones(per_block, dtype=bool)
        valid[5] = k != 2
        batch = SampleBatch(t, {"force_n": force, "depth_m": -0.01 * t}, {"force_n": valid})
        recording.samples("sensor", "wrist", batch, {"force_n": "N", "depth_m": "m"},
                          {"force_n": 250.0, "depth_m": 250.0})
        batches.append(batch)
    recording.close()
    return SampleBatch(
        np.concatenate([b.timestamps_s for b in batches]),
        {n: np.concatenate([b.channels[n] for b in batches]) for n in ("force_n", "depth_m")},
        {"force_n": np.concatenate([b.valid["force_n"] for b in batches])})


def _sensor(**config: object) -> mcap_sensor.RecordingSensor:
    return make_component(SPEC, config=dict(config), interface=mcap_sensor.RecordingSensor)


@pytest.mark.slow
def test_the_conformance_kit_passes_on_the_demo_recording() -> None:
    results = run_checks(SPEC)
    assert results and all(r.status == "PASS" for r in results), [
        r for r in results if r.status != "PASS"]


def test_samples_units_and_rates_come_back_exactly(tmp_path: Path) -> None:
    written = _write(tmp_path / "run")
    sensor = _sensor(file=str(tmp_path / "run"), topic="/sensor/wrist")
    assert {n: (i.shape, i.unit, i.rate_hz) for n, i in sensor.channels.items()} == {
        "force_n": ((2,), "N", 250.0), "depth_m": ((), "m", 250.0)}
    everything = sensor.read_all()
    assert sensor.exhausted
    assert np.array_equal(everything.timestamps_s, written.timestamps_s)
    assert np.array_equal(everything.channels["force_n"], written.channels["force_n"],
                          equal_nan=True)
    assert np.array_equal(everything.channels["depth_m"], written.channels["depth_m"])
    assert np.array_equal(everything.valid["force_n"], written.valid["force_n"])


def test_a_read_delivers_one_recorded_message_or_up_to_a_count(tmp_path: Path) -> None:
    _write(tmp_path / "run")
    sensor = _sensor(file=str(tmp_path / "run" / RECORDING), topic="/sensor/wrist")
    sizes = []
    while not sensor.exhausted:
        sizes.append(len(sensor.read()))
    assert sum(sizes) == 60 and len(sizes) > 1 and len(sensor.read()) == 0
    sensor.reset()
    sensor.deliver_until(17)
    assert len(sensor.read()) == 17 and len(sensor.read()) == 0
    mark = sensor.checkpoint()
    sensor.deliver_until(40)
    assert len(sensor.read()) == 23
    sensor.rewind(mark)
    assert sensor.read().timestamps_s[0] == pytest.approx(17 / 250.0)


def test_pace_waits_for_the_samples_timestamps(tmp_path: Path,
                                               monkeypatch: pytest.MonkeyPatch) -> None:
    _write(tmp_path / "run")
    now = [100.0]
    waits: list[float] = []

    def sleep(seconds: float) -> None:
        waits.append(seconds)
        now[0] += seconds

    monkeypatch.setattr(mcap_sensor, "_monotonic", lambda: now[0])
    monkeypatch.setattr(mcap_sensor, "_sleep", sleep)
    sensor = _sensor(file=str(tmp_path / "run"), topic="/sensor/wrist", pace=True)
    first = sensor.read()
    last_times = [float(first.timestamps_s[-1])]
    while not sensor.exhausted:
        last_times.append(float(sensor.read().timestamps_s[-1]))
    # Each read returns when the wall clock has advanced as far as its last sample's time.
    assert now[0] - 100.0 == pytest.approx(last_times[-1] - last_times[0])
    assert waits and all(w > 0 for w in waits)


def test_a_missing_channel_lists_what_the_recording_holds(tmp_path: Path) -> None:
    _write(tmp_path / "run")
    with pytest.raises(ValueError, match=r"no recorded channel '/sensor/elbow'.*/sensor/wrist"):
        _sensor(file=str(tmp_path / "run"), topic="/sensor/elbow")
    (tmp_path / "empty").mkdir()
    with pytest.raises(ValueError, match="holds no recording"):
        _sensor(file=str(tmp_path / "empty"))
    with pytest.raises(ValueError, match="no such file"):
        _sensor(file=str(tmp_path / "missing.mcap"))
    with pytest.raises(ValueError, match="either 'file'"):
        _sensor(file=str(tmp_path / "run"), demo=True)


def test_the_default_topic_is_the_components_id(tmp_path: Path) -> None:
    _write(tmp_path / "run")
    # make_component builds the component under the id the kit gives it.
    with pytest.raises(ValueError, match="/sensor/"):
        _sensor(file=str(tmp_path / "run"))
