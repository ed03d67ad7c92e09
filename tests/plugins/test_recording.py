"""The ``trace-recording`` sensor: replay, trials per movement, labels, validity, errors."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

from hapticframe.cli._cli import main
from hapticframe.kinds import BuildContext, concatenate_batches
from hapticframe.testing import run_checks
from hapticframe_recording import (
    RecordingError,
    TraceRecordingConfig,
    TraceRecordingSensor,
    load_recording,
)
from hapticframe_recording.plugin import SPECS

PLUGIN = ("--plugin-module", "hapticframe_recording.plugin")
#: Samples per movement of the written trace, and the robot's step period.
MOVEMENT_SAMPLES = (7, 12, 5)
DT = 0.01


def trace_arrays(seed: int = 0) -> dict[str, np.ndarray]:
    """A trace in the run loop's layout: robot ``arm`` (three movements), sensors ``wrist``
    (one sample per robot step, a NaN at step 9) and ``imu`` (twice the rate, starting
    before the robot's first step)."""
    rng = np.random.default_rng(seed)
    n = sum(MOVEMENT_SAMPLES)
    t = (np.arange(n) + 1) * DT
    force = rng.normal(size=(n, 2))
    force[9, 1] = np.nan
    imu_t = t[0] - 0.015 + np.arange(2 * n) * DT / 2
    return {
        "robot/arm/timestamps_s": t,
        "robot/arm/position_m": rng.random((n, 2)),
        "robot/arm/movement_index": np.repeat(np.arange(3), MOVEMENT_SAMPLES).astype(np.int64),
        "sensor/wrist/timestamps_s": t,
        "sensor/wrist/force_n": force,
        "sensor/wrist/torque_nm": rng.normal(size=n),
        "sensor/wrist/force_n/unit": np.array("N"),
        "sensor/wrist/torque_nm/unit": np.array("N m"),
        "sensor/imu/timestamps_s": imu_t,
        "sensor/imu/acceleration_m_per_s2": rng.normal(size=(2 * n, 3)),
        "sensor/imu/acceleration_m_per_s2/unit": np.array("m/s^2"),
        "classifier/jamming/timestamps_s": t,
        "classifier/jamming/classes": np.array(["free", "jamming", "contact"]),
    }


def write(path: Path, arrays: dict[str, np.ndarray]) -> Path:
    np.savez(path, **arrays)
    return path


@pytest.fixture
def trace(tmp_path: Path) -> Path:
    return write(tmp_path / "trace.npz", trace_arrays())


def build(**config: object) -> TraceRecordingSensor:
    return TraceRecordingSensor(
        TraceRecordingConfig.model_validate(config),
        BuildContext(id="replay", rng=np.random.default_rng(0)),
    )


def stream(sensor: TraceRecordingSensor, limit: int = 1000) -> list:
    batches = []
    for _ in range(limit):
        if sensor.exhausted:
            return batches
        batches.append(sensor.read())
    raise AssertionError("the replay did not end")


# --- replay ---------------------------------------------------------------------------------


def test_streaming_replays_exactly_what_was_recorded(trace):
    recorded = trace_arrays()
    sensor = build(path=str(trace), component="wrist", samples_per_read=4)
    assert set(sensor.channels) == {"force_n", "torque_nm"}
    assert sensor.channels["force_n"].shape == (2,) and sensor.channels["force_n"].unit == "N"
    assert sensor.channels["torque_nm"].shape == () and sensor.channels["torque_nm"].unit == "N m"
    assert sensor.channels["force_n"].rate_hz == pytest.approx(100.0, rel=1e-12)
    batches = stream(sensor)
    assert [len(b) for b in batches] == [4, 4, 4, 4, 4, 4]
    whole = concatenate_batches(batches)
    assert np.array_equal(whole.timestamps_s, recorded["sensor/wrist/timestamps_s"])
    assert np.array_equal(whole.channels["force_n"], recorded["sensor/wrist/force_n"],
                          equal_nan=True)
    assert np.array_equal(whole.channels["torque_nm"], recorded["sensor/wrist/torque_nm"])
    assert sensor.read_all().timestamps_s.size == 0  # nothing left


def test_a_run_directory_a_channel_subset_and_the_only_sensor(tmp_path):
    arrays = {k: v for k, v in trace_arrays().items() if not k.startswith("sensor/imu/")}
    write(tmp_path / "trace.npz", arrays)
    sensor = build(path=str(tmp_path), channels=["torque_nm"])  # the only sensor: wrist
    assert list(sensor.channels) == ["torque_nm"]
    assert np.array_equal(sensor.read_all().channels["torque_nm"], arrays["sensor/wrist/torque_nm"])


def test_the_rate_comes_from_the_median_period_or_the_config(trace):
    imu = build(path=str(trace), component="imu")
    assert imu.channels["acceleration_m_per_s2"].rate_hz == pytest.approx(200.0)
    assert build(path=str(trace), component="imu", rate_hz=150.0).channels[
        "acceleration_m_per_s2"].rate_hz == 150.0


# --- trials -----------------------------------------------------------------------------------


def test_one_recording_per_exploratory_movement(trace):
    recordings = list(build(path=str(trace), component="wrist").iter_recordings())
    assert [len(r) for r in recordings] == list(MOVEMENT_SAMPLES)
    t = trace_arrays()["sensor/wrist/timestamps_s"]
    assert np.array_equal(concatenate_batches(recordings).timestamps_s, t)
    assert recordings[1].timestamps_s[0] == t[MOVEMENT_SAMPLES[0]]


def test_a_faster_sensor_is_split_at_the_robot_steps_that_start_movements(trace):
    recordings = list(build(path=str(trace), component="imu").iter_recordings())
    robot_t = trace_arrays()["robot/arm/timestamps_s"]
    starts = [robot_t[0], robot_t[MOVEMENT_SAMPLES[0]], robot_t[sum(MOVEMENT_SAMPLES[:2])]]
    assert len(recordings) == 3
    # The samples before the robot's first step belong to the first movement.
    assert recordings[0].timestamps_s[0] < starts[0]
    for recording, start, end in zip(recordings, starts, [*starts[1:], np.inf], strict=True):
        assert recording.timestamps_s[0] >= start or recording is recordings[0]
        assert recording.timestamps_s[-1] < end
    assert recordings[1].timestamps_s[0] == pytest.approx(starts[1])


def test_one_recording_without_a_robot_or_a_split(tmp_path, trace):
    assert len(list(build(path=str(trace), component="wrist",
                          split_movements=False).iter_recordings())) == 1
    arrays = {k: v for k, v in trace_arrays().items() if not k.startswith("robot/")}
    bare = write(tmp_path / "bare.npz", arrays)
    (only,) = build(path=str(bare), component="wrist").iter_recordings()
    assert len(only) == sum(MOVEMENT_SAMPLES)


def test_recordings_continue_where_reads_stopped(trace):
    sensor = build(path=str(trace), component="wrist", samples_per_read=10)
    first = sensor.read()
    rest = list(sensor.iter_recordings())
    # 7 + 12 + 5 samples; 10 read: the rest of movement 2 (9 samples), then movement 3.
    assert [len(r) for r in rest] == [9, 5]
    assert rest[0].timestamps_s[0] > first.timestamps_s[-1]
    assert sensor.exhausted


# --- labels -----------------------------------------------------------------------------------


def labels_file(tmp_path: Path) -> Path:
    # Labels every 20 ms from 15 ms: 0, 1, 2, 1, 0, ...
    t = 0.015 + 0.02 * np.arange(12)
    return write(tmp_path / "labels.npz", {"timestamps_s": t, "state": np.arange(12) % 3,
                                            "other": np.ones(12)})


def test_labels_are_the_latest_at_or_before_each_sample(tmp_path, trace):
    sensor = build(path=str(trace), component="wrist", labels=str(labels_file(tmp_path)))
    assert sensor.channels["label"].shape == () and sensor.channels["label"].unit == "1"
    batch = sensor.read_all()
    t = batch.timestamps_s
    expected = np.array([np.nan if x < 0.015 else (int((x - 0.015 + 1e-9) // 0.02) % 3)
                         for x in t])
    assert np.array_equal(batch.channels["label"], expected, equal_nan=True)
    assert t[0] == pytest.approx(0.01)
    assert not batch.valid["label"][0] and batch.valid["label"][1:].all()
    assert batch.valid["force_n"][0]  # the force itself was measured


def test_unlabelled_samples_can_be_dropped_and_the_label_channel_named(tmp_path, trace):
    sensor = build(path=str(trace), component="wrist", labels=str(labels_file(tmp_path)),
                   labels_key="other", label_channel="contact", unlabelled="drop")
    batch = sensor.read_all()
    assert batch.timestamps_s[0] == pytest.approx(0.02)
    assert len(batch) == sum(MOVEMENT_SAMPLES) - 1
    assert np.array_equal(batch.channels["contact"], np.ones(len(batch)))


def test_labels_from_a_run_directory_read_its_ground_truth(tmp_path, trace):
    run = tmp_path / "run"
    run.mkdir()
    write(run / "ground_truth.npz", {"timestamps_s": np.array([0.0, 0.05]),
                                     "state": np.array([0, 2])})
    batch = build(path=str(trace), component="wrist", labels=str(run)).read_all()
    assert np.array_equal(batch.channels["label"], np.where(batch.timestamps_s < 0.05, 0, 2))


# --- validity ---------------------------------------------------------------------------------


def test_nan_samples_are_delivered_invalid(trace):
    batch = build(path=str(trace), component="wrist").read_all()
    invalid = ~batch.valid["force_n"]
    assert np.flatnonzero(invalid).tolist() == [9]
    assert np.isnan(batch.channels["force_n"][9, 1])
    assert batch.valid["torque_nm"].all()


def test_recorded_validity_flags_are_honoured(tmp_path):
    arrays = trace_arrays()
    flags = np.ones(sum(MOVEMENT_SAMPLES), dtype=bool)
    flags[3] = False
    arrays["sensor/wrist/torque_nm/valid"] = flags
    batch = build(path=str(write(tmp_path / "t.npz", arrays)), component="wrist").read_all()
    assert np.flatnonzero(~batch.valid["torque_nm"]).tolist() == [3]
    assert "valid" not in build(path=str(tmp_path / "t.npz"), component="wrist").channels


# --- errors -----------------------------------------------------------------------------------


def _without(key: str) -> dict[str, np.ndarray]:
    return {k: v for k, v in trace_arrays().items() if k != key}


@pytest.mark.parametrize(
    ("arrays", "config", "message"),
    [
        (None, {"component": "wirst"}, "holds no recorded sensor 'wirst' (recorded sensors: "
                                       "imu, wrist)"),
        (None, {}, "holds several sensors (imu, wrist); name one in the config"),
        (None, {"component": "wrist", "channels": ["force"]},
         "sensor 'wrist' recorded no channel 'force' (channels: force_n, torque_nm)"),
        (None, {"component": "wrist", "robot": "base"}, "holds no recorded robot 'base'"),
        (_without("sensor/wrist/force_n/unit"), {"component": "wrist"},
         "holds no 'sensor/wrist/force_n/unit'"),
        (_without("robot/arm/movement_index"), {"component": "wrist"},
         "holds no 'robot/arm/movement_index'"),
        ({**trace_arrays(), "sensor/wrist/timestamps_s": np.ones(24)}, {"component": "wrist"},
         "'sensor/wrist/timestamps_s' is not strictly increasing"),
        ({**trace_arrays(), "sensor/wrist/torque_nm": np.ones(5)}, {"component": "wrist"},
         "'sensor/wrist/torque_nm' has shape (5,), expected 24 rows"),
    ],
)
def test_malformed_traces_are_located(tmp_path, arrays, config, message):
    path = write(tmp_path / "trace.npz", trace_arrays() if arrays is None else arrays)
    with pytest.raises(RecordingError) as caught:
        build(path=str(path), **config)
    assert message in str(caught.value)
    assert str(path) in str(caught.value)


def test_missing_files_and_labels_are_located(tmp_path, trace):
    with pytest.raises(RecordingError, match=r"no such file: .*nothing\.npz"):
        build(path=str(tmp_path / "nothing.npz"))
    empty = tmp_path / "empty-run"
    empty.mkdir()
    with pytest.raises(RecordingError, match=r"empty-run holds no trace\.npz"):
        build(path=str(empty))
    with pytest.raises(RecordingError, match=r"empty-run holds no ground_truth\.npz"):
        build(path=str(trace), component="wrist", labels=str(empty))
    with pytest.raises(RecordingError, match=r"holds no 'truth' \(arrays: other, state, "
                                             r"timestamps_s\); set labels_key"):
        build(path=str(trace), component="wrist", labels=str(labels_file(tmp_path)),
              labels_key="truth")
    (tmp_path / "broken.npz").write_bytes(b"not a zip file")
    with pytest.raises(RecordingError, match=r"cannot read .*broken\.npz"):
        build(path=str(tmp_path / "broken.npz"))


def test_pickled_arrays_are_never_loaded(tmp_path):
    arrays = trace_arrays()
    arrays["sensor/wrist/force_n"] = np.array([object()] * 24, dtype=object)
    path = tmp_path / "pickled.npz"
    np.savez(path, **arrays)  # savez pickles object arrays; load must refuse them
    with pytest.raises(RecordingError, match=r"cannot read .*pickled\.npz.*allow_pickle"):
        load_recording(path, component="wrist")


def test_config_needs_exactly_one_source():
    with pytest.raises(ValueError, match="either 'path'"):
        TraceRecordingConfig()
    with pytest.raises(ValueError, match="either 'path'"):
        TraceRecordingConfig(path="x.npz", demo=True)


def test_a_missing_recording_ends_the_run_with_exit_2_and_a_located_message(tmp_path, capsys):
    experiment = tmp_path / "replay.yaml"
    experiment.write_text(
        "schema_version: 1\nname: replay\nseed: 1\nsensors:\n  - id: wrist\n"
        "    type: trace-recording\n"
        f"    config: {{path: {tmp_path / 'missing'}}}\n"
    )
    assert main(["run", *PLUGIN, str(experiment), "--out", str(tmp_path / "out"),
                 "--quiet"]) == 2
    err = capsys.readouterr().err
    assert "cannot build 'wrist'" in err and "no such file" in err and "missing" in err
    assert "Traceback" not in err


# --- the conformance kit ----------------------------------------------------------------------


def test_the_registered_spec_passes_the_kit():
    results = run_checks(SPECS[0])
    assert [r for r in results if r.status != "PASS"] == []


def test_the_kit_passes_on_a_written_trace_with_labels(tmp_path, trace):
    spec = dataclasses.replace(SPECS[0], check_config={
        "path": str(trace), "component": "wrist", "labels": str(labels_file(tmp_path)),
        "samples_per_read": 5,
    })
    results = run_checks(spec)
    assert [r for r in results if r.status != "PASS"] == []
    assert len(results) >= 8
