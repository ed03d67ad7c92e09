"""The ``recording`` sensor's tare: a BioTac bag imported with ``import-bag`` and a CSV of
the same frames, replayed through the ``recording`` and ``biotac`` sensors with the same
tare, give exactly the same features; import-bag records each stream's nominal rate."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest

pytest.importorskip("rosbags")

from rosbags.rosbag1 import Writer
from rosbags.typesys import Stores, get_typestore

from hapticframe.kinds import BuildContext
from hapticframe.record._bags import biotac_types, import_bag, parse_map
from hapticframe_biotac import BioTacSensor, BioTacSensorConfig
from hapticframe_recording import McapRecordingConfig, RecordingSensor
from hapticframe_tactile_features import EMDFeatureExtractor, EMDFeaturesConfig
from tests.support.bolt_fixture import press_finger

START_NS = 1_342_570_000 * 1_000_000_000 + 400_000_000


def _store() -> Any:
    store = get_typestore(Stores.ROS1_NOETIC)
    store.register(biotac_types())
    return store


def _header(store: Any, stamp_ns: int) -> Any:
    time = store.types["builtin_interfaces/msg/Time"](
        sec=stamp_ns // 1_000_000_000, nanosec=stamp_ns % 1_000_000_000)
    return store.types["std_msgs/msg/Header"](seq=0, stamp=time, frame_id="tip")


def _hand(store: Any, header: Any, f: dict[str, Any]) -> Any:
    t = store.types
    zero = t["builtin_interfaces/msg/Time"](sec=0, nanosec=0)
    data = t["biotac_sensors/msg/BioTacData"](
        bt_serial="BT0001", bt_position=1, tdc_data=int(f["tdc"]), tac_data=int(f["tac"]),
        pdc_data=int(f["pdc"]), pac_data=np.asarray(f["pac"], dtype=np.uint16),
        electrode_data=np.asarray(f["electrodes"], dtype=np.uint16))
    bt_time = t["biotac_sensors/msg/BioTacTime"](
        frame_start_time=zero, frame_end_time=zero, tdc_ns_offset=0, tac_ns_offset=0,
        pdc_ns_offset=0, pac_ns_offset=np.zeros(22, dtype=np.uint32),
        electrode_ns_offset=np.zeros(19, dtype=np.uint32))
    return t["biotac_sensors/msg/BioTacHand"](header=header, hand_id="h", bt_data=[data],
                                              bt_time=bt_time)


def _write(bag: Path, frames: dict[str, np.ndarray], wrench_ns: np.ndarray | None = None) -> None:
    store = _store()
    n = frames["pdc"].size
    with Writer(bag) as writer:
        hand = writer.add_connection("/biotac_pub", "biotac_sensors/msg/BioTacHand",
                                     typestore=store)
        for k in range(n):
            stamp = START_NS + k * 10_000_000
            row = {c: v[k] for c, v in frames.items()}
            writer.write(hand, stamp, store.serialize_ros1(
                _hand(store, _header(store, stamp), row), "biotac_sensors/msg/BioTacHand"))
        if wrench_ns is not None:
            kind = "geometry_msgs/msg/WrenchStamped"
            conn = writer.add_connection("/wrench", kind, typestore=store)
            v3 = store.types["geometry_msgs/msg/Vector3"]
            for stamp in wrench_ns:
                msg = store.types[kind](header=_header(store, int(stamp)), wrench=store.types[
                    "geometry_msgs/msg/Wrench"](force=v3(x=1.0, y=0.0, z=0.0),
                                                torque=v3(x=0.0, y=0.0, z=0.0)))
                writer.write(conn, int(stamp), store.serialize_ros1(msg, kind))


def _csv(path: Path, frames: dict[str, np.ndarray], times: np.ndarray) -> None:
    header = (["timestamp", "pdc", "tac", "tdc"] + [f"pac{i}" for i in range(1, 23)]
              + [f"ele{i}" for i in range(1, 20)])
    table = np.column_stack([times, frames["pdc"], frames["tac"], frames["tdc"],
                             frames["pac"], frames["electrodes"]])
    path.write_text(",".join(header) + "\n"
                    + "".join(",".join(repr(float(v)) for v in row) + "\n" for row in table))


def _features(batch: Any) -> dict[str, np.ndarray]:
    extractor = EMDFeatureExtractor(EMDFeaturesConfig(),
                                    BuildContext("emd", np.random.default_rng(0)))
    out = extractor.transform(batch)
    return {name: np.asarray(v) for name, v in out.channels.items()} | {
        "t": np.asarray(out.timestamps_s)}


def test_imported_bag_and_csv_replay_give_the_same_features(tmp_path: Path) -> None:
    n, tare = 260, 40
    frames = press_finger(np.random.default_rng(11), n, (80, 200))
    _write(tmp_path / "tip.bag", frames)
    import_bag(tmp_path / "tip.bag", [parse_map("/biotac_pub=tip")], tmp_path / "imported")
    recorded = RecordingSensor(
        McapRecordingConfig(file=str(tmp_path / "imported"), tare_frames=tare),
        BuildContext("tip", np.random.default_rng(0)))
    from_bag = recorded.read_all()
    times = np.asarray(from_bag.timestamps_s)
    _csv(tmp_path / "tip.csv", frames, times)
    replay = BioTacSensor(
        BioTacSensorConfig(source="replay", path=str(tmp_path / "tip.csv"), tare_frames=tare,
                           frames_per_read=10_000),
        BuildContext("tip", np.random.default_rng(0)))
    from_csv = replay.read()
    for name in ("pac", "pdc", "electrodes"):
        np.testing.assert_array_equal(np.asarray(from_bag.channels[name]),
                                      np.asarray(from_csv.channels[name]), err_msg=name)
    assert abs(np.asarray(from_bag.channels["pdc"])[:tare]).max() < 10  # zeroed at rest
    bag_features, csv_features = _features(from_bag), _features(from_csv)
    assert bag_features.keys() == csv_features.keys() and bag_features["t"].size > 100
    for name, values in bag_features.items():
        np.testing.assert_array_equal(values, csv_features[name], err_msg=name)
    # Without the tare the recording sensor delivers raw counts: the features differ.
    raw = RecordingSensor(McapRecordingConfig(file=str(tmp_path / "imported")),
                          BuildContext("tip", np.random.default_rng(0))).read_all()
    assert not np.array_equal(np.asarray(raw.channels["pdc"]), from_csv.channels["pdc"])


def test_tare_channels_and_invalid_samples(tmp_path: Path) -> None:
    config = McapRecordingConfig(demo=True, topic="/sensor/x", tare_frames=5)
    sensor = RecordingSensor(config, BuildContext("x", np.random.default_rng(0)))
    raw = RecordingSensor(McapRecordingConfig(demo=True, topic="/sensor/x"),
                          BuildContext("x", np.random.default_rng(0))).read_all()
    force = np.asarray(raw.channels["force_n"])
    tared = np.asarray(sensor.read_all().channels["force_n"])
    # The demo holds no invalid sample in the first five: the reference is their mean.
    np.testing.assert_allclose(tared[10:], force[10:] - force[:5].mean(axis=0))
    np.testing.assert_allclose(tared[0], 0.0)
    with pytest.raises(ValueError, match="tare_channels names 'nope'"):
        RecordingSensor(McapRecordingConfig(demo=True, topic="/sensor/x", tare_frames=5,
                                            tare_channels=("nope",)),
                        BuildContext("x", np.random.default_rng(0)))
    with pytest.raises(ValueError, match="tare_channels needs tare_frames"):
        McapRecordingConfig(demo=True, tare_channels=("force_n",))


def test_import_bag_records_nominal_rates(tmp_path: Path) -> None:
    """A jittery 87 Hz wrench: its mean rate is recorded (the median period says 150 Hz)."""
    frames = press_finger(np.random.default_rng(2), 50, (10, 40))
    # Periods alternate 6.67 ms and 16.3 ms: mean 11.49 ms (87 Hz), median 6.67 ms.
    periods = np.tile([6_666_667, 16_321_839], 40)[:79]
    wrench = START_NS + np.concatenate([[0], np.cumsum(periods)])
    _write(tmp_path / "w.bag", frames, wrench)
    result = import_bag(tmp_path / "w.bag", [parse_map("/biotac_pub=tip"),
                                             parse_map("/wrench=ft")], tmp_path / "out")
    mean_rate = 79 / ((wrench[-1] - wrench[0]) / 1e9)
    assert result.sensors["ft"]["rate_hz"] == pytest.approx(mean_rate)
    assert 86 < mean_rate < 88
    assert result.sensors["tip"]["rate_hz"] == 100.0
    ft = RecordingSensor(McapRecordingConfig(file=str(tmp_path / "out"), topic="/sensor/ft"),
                         BuildContext("ft", np.random.default_rng(0)))
    assert ft.channels["force_n"].rate_hz == pytest.approx(mean_rate)
    tip = RecordingSensor(McapRecordingConfig(file=str(tmp_path / "out"), topic="/sensor/tip"),
                          BuildContext("tip", np.random.default_rng(0)))
    assert {info.rate_hz for info in tip.channels.values()} == {100.0}
