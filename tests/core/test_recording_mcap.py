"""``run.mcap``: every run recorded as it happens, synced, and recovered after a kill."""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml
from mcap.reader import make_reader

from hapticframe.cli._cli import main
from hapticframe.kinds import ClassProbabilities, SampleBatch
from hapticframe.record._recording import RECORDING, RunRecording, read_recording
from hapticframe.record._recover import recover
from hapticframe.run._results import STAGING
from tests.core.test_outputs_atomic import kill_self, killed_at, needs_fork, record, run

ROOT = Path(__file__).resolve().parents[2]


def _joined(messages: list[tuple[int, dict[str, Any]]], *path: str) -> np.ndarray:
    parts = []
    for _, data in messages:
        for name in path:
            data = data[name]
        parts.append(np.array(data, dtype=float))
    return np.concatenate(parts)


@pytest.fixture(scope="module")
def search(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The README's main job (a closed-loop search), figures off, run once."""
    folder = tmp_path_factory.mktemp("search")
    model = yaml.safe_load((ROOT / "examples" / "search-ellipse.yaml").read_text())
    model["run"]["figures"] = False
    experiment = folder / "search.yaml"
    experiment.write_text(yaml.safe_dump(model))
    out = folder / "out"
    assert main(["run", str(experiment), "--out", str(out), "--quiet"]) == 0
    return out


def test_a_run_records_what_its_trace_holds(search):
    assert "run.mcap" in record(search)["files"]
    trace = np.load(search / "trace.npz")
    recorded = read_recording(search / RECORDING)
    pairs = {
        ("/sensor/wrist", ("timestamps_s",)): "sensor/wrist/timestamps_s",
        ("/sensor/wrist", ("channels", "force_n")): "sensor/wrist/force_n",
        ("/classifier/jamming", ("probabilities",)): "classifier/jamming/probabilities",
        ("/classifier/jamming", ("timestamps_s",)): "classifier/jamming/timestamps_s",
        ("/robot/arm/state", ("positions_m",)): "robot/arm/position_m",
        ("/robot/arm/state", ("movement_index",)): "robot/arm/movement_index",
        ("/sensor_model/failure-zone/observations", ("points_m",)):
            "sensor_model/failure-zone/points_m",
        ("/sensor_model/failure-zone/observations", ("weights",)):
            "sensor_model/failure-zone/weights",
    }
    for (topic, path), key in pairs.items():
        np.testing.assert_array_equal(_joined(recorded[topic], *path), trace[key], err_msg=key)
    # Arrays per block, not a message per sample.
    assert len(recorded["/sensor/wrist"]) < len(trace["sensor/wrist/timestamps_s"]) / 10
    assert recorded["/sensor/wrist"][0][1]["units"] == {"force_n": "N"}
    classes = recorded["/classifier/jamming"][0][1]["classes"]
    assert classes == list(trace["classifier/jamming/classes"])
    located = _joined(recorded["/sensor_model/failure-zone/located"], "timestamps_s")
    assert len(located) and set(located) <= set(trace["classifier/jamming/timestamps_s"])
    metrics = json.loads((search / "metrics.json").read_text())
    movements = [data for _, data in recorded["/movement"]]
    assert [m["index"] for m in movements] == list(range(metrics["movements"]))
    assert all(isinstance(m["halted"], bool) for m in movements)
    # The indexed reader reads it too, with the channels' JSON schemas.
    with open(search / RECORDING, "rb") as stream:
        summary = make_reader(stream).get_summary()
    assert summary is not None and summary.statistics is not None
    assert summary.statistics.message_count == sum(len(v) for v in recorded.values())
    assert {s.encoding for s in summary.schemas.values()} == {"jsonschema"}
    assert {c.message_encoding for c in summary.channels.values()} == {"json"}


class _Clock:
    def __init__(self) -> None:
        self.now = 0.0

    def __call__(self) -> float:
        return self.now


def _synthetic(path: Path) -> list[int]:
    """A recording of 40 sensor batches and classifier outputs, synced every 4th batch
    (a fake wall clock); returns the message count at each sync."""
    clock = _Clock()
    recording = RunRecording(path, {"name": "synthetic"}, clock=clock, block_s=0.05)
    rng = np.random.default_rng(0)
    synced = []
    for k in range(40):
        t = 0.1 * k + 0.01 * np.arange(10, dtype=np.float64)
        force = rng.normal(size=(10, 3))
        recording.samples("sensor", "s", SampleBatch(t, {"force_n": force}), {"force_n": "N"})
        p = rng.uniform(size=10)
        recording.probabilities("c", ClassProbabilities(t, np.column_stack([p, 1 - p]),
                                                        ("none", "contact")))
        if k % 4 == 3:
            clock.now += 1.0
            recording.sync()
            synced.append(recording.messages)
    recording.close()
    return synced


@pytest.mark.parametrize("fraction", [0.05, 0.3, 0.55, 0.8, 0.97, 0.999])
def test_a_truncated_recording_is_recovered_up_to_the_cut(tmp_path, fraction, capsys):
    full = tmp_path / "full.mcap"
    _synthetic(full)
    original = read_recording(full)
    with open(full, "rb") as stream:
        summary = make_reader(stream).get_summary()
    assert summary is not None and len(summary.chunk_indexes) >= 10
    data = full.read_bytes()
    cut = int(len(data) * fraction)
    cut_file = tmp_path / "cut" / RECORDING
    cut_file.parent.mkdir()
    cut_file.write_bytes(data[:cut])
    # Every chunk that ended before the cut is recovered.
    whole = [c for c in summary.chunk_indexes
             if c.chunk_start_offset + c.chunk_length + c.message_index_length <= cut]
    target = cut_file.with_name("run.recovered.mcap")
    if not any(c.chunk_start_offset + c.chunk_length <= cut for c in summary.chunk_indexes):
        # Not one whole chunk: nothing to recover, said so (exit 1), nothing written.
        assert main(["recover", str(cut_file.parent)]) == 1
        assert "not one message of" in capsys.readouterr().err
        assert not target.exists() and cut_file.read_bytes() == data[:cut]
        return
    assert main(["recover", str(cut_file.parent)]) == 0
    out = capsys.readouterr().out
    assert "cut short" in out and f"wrote {target}" in out
    assert cut_file.read_bytes() == data[:cut]  # written beside, never in place
    recovered = read_recording(target)
    kept = sum(len(v) for v in recovered.values())
    for topic, messages in recovered.items():
        assert messages == original[topic][:len(messages)]  # a prefix, exactly
    if whole:
        latest = max(c.message_end_time for c in whole)
        assert max(t for v in recovered.values() for t, _ in v) >= latest
    assert kept <= sum(len(v) for v in original.values())
    # The result is a complete, indexed recording.
    with open(target, "rb") as stream:
        reader = make_reader(stream)
        assert sum(1 for _ in reader.iter_messages()) == kept


def test_a_complete_recording_is_rewritten_unchanged(tmp_path):
    source = tmp_path / "a.mcap"
    _synthetic(source)
    result = recover(source, tmp_path / "b.mcap")
    assert result.cut == "" and result.messages == sum(result.counts.values()) > 0
    assert read_recording(tmp_path / "b.mcap") == read_recording(source)
    assert result.start_s == 0.09 and result.end_s == pytest.approx(3.99)


@needs_fork
@pytest.mark.parametrize("point", ["at-sync", "between-syncs"])
def test_kill_9_mid_run_leaves_a_recoverable_recording(lab_dir, point, capsys):
    experiment = lab_dir / "lab-open-loop.yaml"
    experiment.write_text(experiment.read_text() + "run: {figures: false}\n")
    out = lab_dir / "run"
    counts = lab_dir / "counts.json"

    def patch() -> None:
        # Sync at every record (a wall clock of seconds per sample), kill after the 6th.
        defaults = RunRecording.__init__.__kwdefaults__
        assert defaults is not None
        defaults["sync_s"] = 0.0
        real_sync, real_write = RunRecording.sync, RunRecording._write
        synced: list[int] = []

        def sync(self: RunRecording) -> None:
            real_sync(self)
            synced.append(self.messages)
            counts.write_text(json.dumps(synced))
            if point == "at-sync" and len(synced) == 6:
                kill_self()

        def write(self: RunRecording, *args: Any) -> None:
            real_write(self, *args)
            if point == "between-syncs" and len(synced) >= 6:
                kill_self()  # a message written, not yet synced

        RunRecording.sync = sync  # type: ignore[method-assign]
        RunRecording._write = write  # type: ignore[method-assign,assignment]

    killed_at(patch, ["run", str(experiment), "--out", str(out), "--quiet"])
    assert record(out)["status"] == "running"
    left = out / STAGING / RECORDING
    assert left.is_file() and not (out / RECORDING).exists()
    synced = json.loads(counts.read_text())[-1]
    capsys.readouterr()
    assert main(["recover", str(out)]) == 0
    assert f"{synced} messages on" in capsys.readouterr().out
    recovered = read_recording(out / RECORDING)
    assert sum(len(v) for v in recovered.values()) == synced
    assert "/sensor/sweep" in recovered and "/classifier/contact" in recovered
    assert RECORDING in record(out)["files"]  # --overwrite may clear it later
    assert run(experiment, out, "--overwrite") == 0


def test_what_is_not_a_recording_is_refused_with_its_name(tmp_path, capsys):
    bogus = tmp_path / "run.mcap"
    bogus.write_bytes(b"PK\x03\x04 not a recording")
    assert main(["recover", str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert f"{bogus} is not an MCAP recording" in err and "Traceback" not in err
    assert bogus.read_bytes() == b"PK\x03\x04 not a recording"
    empty = tmp_path / "empty"
    empty.mkdir()
    assert main(["recover", str(empty)]) == 2
    assert "holds no recording" in capsys.readouterr().err
    assert main(["recover", str(tmp_path / "missing.mcap")]) == 2
    assert "no such file" in capsys.readouterr().err


def test_a_run_can_record_nothing(lab_dir):
    experiment = lab_dir / "lab-open-loop.yaml"
    experiment.write_text(experiment.read_text() + "run: {figures: false, record: false}\n")
    out = lab_dir / "run"
    assert run(experiment, out) == 0
    assert not (out / RECORDING).exists() and RECORDING not in record(out)["files"]
    assert not os.path.exists(out / STAGING)


def _reference_json(value: Any) -> Any:
    """What a message holds, made by hand: lists of Python floats, non-finite ones None."""
    if isinstance(value, dict):
        return {k: _reference_json(v) for k, v in value.items()}
    if isinstance(value, np.ndarray):
        return _reference_json(value.tolist())
    if isinstance(value, (list, tuple)):
        return [_reference_json(v) for v in value]
    if isinstance(value, np.generic):
        return _reference_json(value.item())
    if isinstance(value, float) and not np.isfinite(value):
        return None
    return value


def test_messages_hold_arrays_as_json_reads_them_back_to_the_bit() -> None:
    """The encoder reads arrays in place (orjson); the reference is :mod:`json` of their
    lists. Views, other dtypes, non-finite values and numpy scalars included."""
    from hapticframe.record._recording import decode_message, encode_message

    rng = np.random.default_rng(3)
    grid = rng.normal(size=(40, 6)) * 10.0 ** rng.integers(-300, 300, size=(40, 6))
    grid[3, 2], grid[5, 1], grid[7, 4] = np.nan, np.inf, -np.inf
    data = {
        "dense": grid,
        "view": grid[::3, 1::2],  # not contiguous
        "fortran": np.asfortranarray(grid),
        "big_endian": grid.astype(">f8"),
        "ints": np.arange(-5, 5, dtype=np.int32),
        "flags": grid > 0,
        "nested": {"empty": np.zeros((0, 2)), "scalar": np.float64(np.nan),
                   "count": np.int64(7), "tiny": np.array([5e-324, -0.0])},
        "rows": [(1.5, [0.25, float("nan")], 3)],
    }
    payload = encode_message(data)
    assert json.loads(payload) == _reference_json(data)
    decoded = decode_message(payload)
    read_back = np.where(np.isfinite(grid), grid, np.nan)  # null reads back as NaN
    assert np.array_equal(np.array(decoded["dense"], dtype=float), read_back, equal_nan=True)
    assert np.array_equal(np.array(decoded["view"], dtype=float), read_back[::3, 1::2],
                          equal_nan=True)
    assert decoded["nested"]["empty"] == []
    with pytest.raises(TypeError, match="cannot hold object"):
        encode_message({"what": object()})


def test_float32_samples_are_recorded_as_their_float64_values(tmp_path: Path) -> None:
    """A sensor's float32 channel reads back as the same numbers in float64 (not float32's
    shortest decimal, which is another float64)."""
    values = np.array([[0.1], [1 / 3], [2.0 ** -140]], dtype=np.float32)
    recording = RunRecording(tmp_path / RECORDING)
    recording.samples("sensor", "cheap", SampleBatch(
        np.array([0.0, 0.01, 0.02]), {"force": values}))
    recording.close()
    [(_, data)] = read_recording(tmp_path / RECORDING)["/sensor/cheap"]
    assert np.array_equal(np.array(data["channels"]["force"]), values.astype(np.float64))
