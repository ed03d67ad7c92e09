"""Penn BOLT HDF5 recordings: every trial and both fingers as raw counts, a rebuilt 100 Hz
clock, located errors, and the biotac sensor's replay of one trial."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("h5py")

import h5py

from hapticframe.kinds import BuildContext
from hapticframe_biotac import (
    BioTacSensor,
    BioTacSensorConfig,
    ReplayFormatError,
    load_bolt,
    load_bolt_dir,
    rebuild_frame_clock,
    save_bolt,
    tare_frames,
)
from tests.support.bolt_fixture import bolt_trials, write_bolt_dir


def _brute_force_phase(stamps: np.ndarray) -> tuple[float, int]:
    """The best phase on a 1 ms grid by counting matches directly (the reference)."""
    k = np.arange(stamps.size) / 100.0
    best = (-1, 0.0)
    for phase in np.arange(0, 1000) / 1000.0:
        hits = int(np.sum(np.floor(np.round(phase + k, 9)) + stamps[0] == stamps))
        if hits > best[0]:
            best = (hits, phase)
    return best[1], stamps.size - best[0]


def test_clock_rebuilt_from_whole_seconds() -> None:
    # 60 frames in the first second, then 100 a second: the first frame is 0.4 s in.
    stamps = 1000 + (np.arange(360) + 40) // 100
    times, start, mismatched = rebuild_frame_clock(stamps)
    assert np.allclose(np.diff(times), 0.01) and times[0] == 0.0
    assert start == pytest.approx(1000.4) and mismatched == 0
    # A second of 99 frames (the BioTac's clock is not the host's): no phase fits all.
    stamps = np.concatenate([1000 + (np.arange(140) + 60) // 100,
                             np.full(99, 1002), np.full(100, 1003)])
    _, start, mismatched = rebuild_frame_clock(stamps)
    phase, reference = _brute_force_phase(stamps)
    assert mismatched == reference > 0
    assert start - 1000 == pytest.approx(phase, abs=0.0105)
    assert rebuild_frame_clock(np.array([5]))[1:] == (5.0, 0)
    assert rebuild_frame_clock(np.array([], dtype=np.int64))[0].size == 0


def test_every_trial_and_both_fingers_raw(tmp_path: Path) -> None:
    rng = np.random.default_rng(3)
    trials = bolt_trials(rng, "cork", count=3, n=250)
    path = save_bolt(tmp_path / "cork.h5", trials)
    loaded = load_bolt(path)
    assert [(t.trial, t.finger) for t in loaded] == [
        (f"cork_{k:02d}", f) for k in (1, 2, 3) for f in (0, 1)]
    for t in loaded:
        stamps, fingers = trials[t.trial]
        for channel in ("pac", "pdc", "tac", "tdc", "electrodes"):
            np.testing.assert_array_equal(getattr(t.frames, channel), fingers[t.finger][channel])
        meta = t.recording.metadata
        assert meta["object"] == "cork" and meta["clock_mismatched_frames"] == 0
        assert "rebuilt" in meta["clock"] and "whole seconds" in meta["clock"]
        assert meta["start_time_s"] == pytest.approx(stamps[0] + 0.6)
        assert not t.frames.has_ground_truth
    assert [t.trial for t in load_bolt(path, ["cork_02"])] == ["cork_02", "cork_02"]
    write_bolt_dir(tmp_path / "dir", ("a", "b"), count=1, n=120)
    assert [t.object for t in load_bolt_dir(tmp_path / "dir")] == ["a", "a", "b", "b"]


def test_bad_files_are_located(tmp_path: Path) -> None:
    rng = np.random.default_rng(4)
    path = save_bolt(tmp_path / "x.h5", bolt_trials(rng, "x", count=1, n=120))
    with pytest.raises(ReplayFormatError, match="no trial 'x_09'; it holds x_01"):
        load_bolt(path, ["x_09"])
    with h5py.File(path, "a") as f:
        del f["x_01/finger_1/pdc"]
    with pytest.raises(ReplayFormatError, match=r"x\.h5: /x_01/finger_1/pdc: missing"):
        load_bolt(path)
    path = save_bolt(tmp_path / "y.h5", bolt_trials(rng, "y", count=1, n=120))
    with h5py.File(path, "a") as f:
        data = f["y_01/finger_0/electrodes"][()]
        del f["y_01/finger_0/electrodes"]
        f["y_01/finger_0/electrodes"] = data[:, :18]
    with pytest.raises(ReplayFormatError, match="electrodes"):
        load_bolt(path)
    path = save_bolt(tmp_path / "z.h5", bolt_trials(rng, "z", count=1, n=120))
    with h5py.File(path, "a") as f:
        pdc = f["z_01/finger_0/pdc"][()].astype(float)
        pdc[7] = np.nan
        del f["z_01/finger_0/pdc"]
        f["z_01/finger_0/pdc"] = pdc
    with pytest.raises(ReplayFormatError, match="pdc: row 7 is not finite"):
        load_bolt(path)
    (tmp_path / "text.h5").write_text("not hdf5")
    with pytest.raises(ReplayFormatError, match="not an HDF5 file"):
        load_bolt(tmp_path / "text.h5")
    with pytest.raises(ReplayFormatError, match="no such file"):
        load_bolt(tmp_path / "missing.h5")
    (tmp_path / "empty").mkdir()
    with pytest.raises(ReplayFormatError, match=r"holds no \.h5 files"):
        load_bolt_dir(tmp_path / "empty")


def test_biotac_sensor_replays_a_bolt_trial_tared(tmp_path: Path) -> None:
    write_bolt_dir(tmp_path, ("cork",), count=2, n=300, seed=5)
    config = BioTacSensorConfig(source="replay", path=str(tmp_path / "cork.h5"),
                                bolt_trial="cork_02", bolt_finger=1, tare_frames=50,
                                frames_per_read=1000)
    sensor = BioTacSensor(config, BuildContext("tip", np.random.default_rng(0)))
    frames = sensor.read_frames()
    expected = tare_frames(load_bolt(tmp_path / "cork.h5", ["cork_02"])[1].frames, 50)
    np.testing.assert_array_equal(frames.pdc, expected.pdc)
    assert abs(frames.pdc[:50]).max() < 10 and frames.pdc[150] > 60  # rest 0, press up
    assert sensor.metadata["finger"] == 1 and "position_m" not in sensor.channels
    with pytest.raises(ValueError, match="needs bolt_trial"):
        BioTacSensorConfig(source="replay", path="cork.h5")
