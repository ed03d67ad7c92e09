"""``hapticframe import-bag``: small ROS 1 and ROS 2 bags, written here by rosbags, round-trip
exactly into the recording the ``recording`` sensor source reads."""

from __future__ import annotations

import json
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from hapticframe._errors import UsageError
from hapticframe.cli._cli import main
from hapticframe.record._bags import SUPPORTED_TYPES, biotac_types, import_bag, parse_map
from hapticframe.record._recording import read_recording

pytest.importorskip("rosbags")

from rosbags.rosbag1 import Writer as Writer1
from rosbags.rosbag2 import StoragePlugin
from rosbags.rosbag2 import Writer as Writer2
from rosbags.typesys import Stores, get_typestore

#: 2023-11-14T22:13:20Z, a bag's absolute start.
EPOCH_S = 1_700_000_000


def _store(ros1: bool) -> Any:
    store = get_typestore(Stores.ROS1_NOETIC if ros1 else Stores.ROS2_HUMBLE)
    store.register(biotac_types())
    return store


def _header(store: Any, stamp_ns: int, ros1: bool) -> Any:
    time = store.types["builtin_interfaces/msg/Time"](
        sec=stamp_ns // 1_000_000_000, nanosec=stamp_ns % 1_000_000_000)
    header = store.types["std_msgs/msg/Header"]
    return header(seq=0, stamp=time, frame_id="tip") if ros1 else header(stamp=time,
                                                                          frame_id="tip")


def _vector(store: Any, v: np.ndarray) -> Any:
    return store.types["geometry_msgs/msg/Vector3"](x=v[0], y=v[1], z=v[2])


def _wrench(store: Any, header: Any, force: np.ndarray, torque: np.ndarray) -> Any:
    t = store.types
    return t["geometry_msgs/msg/WrenchStamped"](
        header=header, wrench=t["geometry_msgs/msg/Wrench"](
            force=_vector(store, force), torque=_vector(store, torque)))


def _imu(store: Any, header: Any, gyro: np.ndarray, acc: np.ndarray, q_xyzw: np.ndarray,
         no_orientation: bool) -> Any:
    cov = np.zeros(9)
    orientation_cov = cov.copy()
    if no_orientation:
        orientation_cov[0] = -1.0
    return store.types["sensor_msgs/msg/Imu"](
        header=header,
        orientation=store.types["geometry_msgs/msg/Quaternion"](
            x=q_xyzw[0], y=q_xyzw[1], z=q_xyzw[2], w=q_xyzw[3]),
        orientation_covariance=orientation_cov, angular_velocity=_vector(store, gyro),
        angular_velocity_covariance=cov, linear_acceleration=_vector(store, acc),
        linear_acceleration_covariance=cov)


def _biotac_hand(store: Any, header: Any, fingers: Sequence[dict[str, Any]]) -> Any:
    t = store.types
    zero = t["builtin_interfaces/msg/Time"](sec=0, nanosec=0)
    data = [t["biotac_sensors/msg/BioTacData"](
        bt_serial=f["serial"], bt_position=f["position"], tdc_data=f["tdc"], tac_data=f["tac"],
        pdc_data=f["pdc"], pac_data=np.asarray(f["pac"], dtype=np.uint16),
        electrode_data=np.asarray(f["electrodes"], dtype=np.uint16)) for f in fingers]
    bt_time = t["biotac_sensors/msg/BioTacTime"](
        frame_start_time=zero, frame_end_time=zero, tdc_ns_offset=0, tac_ns_offset=0,
        pdc_ns_offset=0, pac_ns_offset=np.zeros(22, dtype=np.uint32),
        electrode_ns_offset=np.zeros(19, dtype=np.uint32))
    return t["biotac_sensors/msg/BioTacHand"](header=header, hand_id="hand", bt_data=data,
                                              bt_time=bt_time)


class _Truth:
    """The values written into a bag, by sensor: stamps (ns) and channels."""

    def __init__(self) -> None:
        self.stamps: dict[str, list[int]] = {}
        self.channels: dict[str, dict[str, list[Any]]] = {}

    def add(self, sensor: str, stamp_ns: int, **channels: Any) -> None:
        self.stamps.setdefault(sensor, []).append(stamp_ns)
        for name, value in channels.items():
            self.channels.setdefault(sensor, {}).setdefault(name, []).append(value)


def _write_bag(path: Path, ros: str, *, n: int = 30, fingers: int = 1,
               rng: np.random.Generator | None = None,
               extra: Callable[[Any, Any], None] | None = None) -> _Truth:
    """A bag with a 100 Hz wrench, a 200 Hz IMU and a 100 Hz BioTac hand (``n`` frames),
    each stamped with its own header time; returns what was written."""
    rng = rng if rng is not None else np.random.default_rng(7)
    ros1 = ros == "ros1"
    store = _store(ros1)
    truth = _Truth()
    if ros1:
        writer: Any = Writer1(path)
        serialize = store.serialize_ros1
    else:
        writer = Writer2(path, version=9,
                         storage_plugin=StoragePlugin.MCAP if ros == "ros2-mcap"
                         else StoragePlugin.SQLITE3)
        serialize = store.serialize_cdr
    with writer:
        def add(topic: str, msgtype: str) -> Any:
            return writer.add_connection(topic, msgtype, typestore=store)

        wrench = add("/ft/wrench", "geometry_msgs/msg/WrenchStamped")
        imu = add("/imu/data", "sensor_msgs/msg/Imu")
        hand = add("/biotac_pub", "biotac_sensors/msg/BioTacHand")
        add("/rosout_like", "std_msgs/msg/String")
        start = EPOCH_S * 1_000_000_000 + 123_456_789
        messages = []
        for k in range(n):
            stamp = start + k * 10_000_000
            force, torque = rng.normal(size=3), rng.normal(size=3)
            messages.append((stamp + 2_000_000, wrench, "geometry_msgs/msg/WrenchStamped",
                             _wrench(store, _header(store, stamp, ros1), force, torque)))
            truth.add("ft", stamp, force_n=force, torque_nm=torque)
            for half in range(2):
                s = stamp + half * 5_000_000 + 1_000
                gyro, acc = rng.normal(size=3), rng.normal(size=3) + [0, 0, 9.81]
                q = rng.normal(size=4)
                q /= np.linalg.norm(q)
                blind = k == 3
                messages.append((s + 1_000_000, imu, "sensor_msgs/msg/Imu",
                                 _imu(store, _header(store, s, ros1), gyro, acc, q, blind)))
                truth.add("imu", s, angular_velocity_rad_per_s=gyro, acceleration_m_per_s2=acc,
                          orientation_wxyz=np.array([q[3], q[0], q[1], q[2]]),
                          orientation_valid=not blind)
            tips = []
            for f in range(fingers):
                tip = {"serial": f"BT{f:04d}", "position": f + 1,
                       "pdc": int(rng.integers(0, 4096)), "tac": int(rng.integers(0, 4096)),
                       "tdc": int(rng.integers(0, 4096)),
                       "pac": rng.integers(0, 4096, size=22),
                       "electrodes": rng.integers(0, 4096, size=19)}
                tips.append(tip)
                truth.add(f"tip{f + 1}", stamp + 7_000, pdc=tip["pdc"], tac=tip["tac"],
                          tdc=tip["tdc"], pac=tip["pac"], electrodes=tip["electrodes"])
            messages.append((stamp + 3_000_000, hand, "biotac_sensors/msg/BioTacHand",
                             _biotac_hand(store, _header(store, stamp + 7_000, ros1), tips)))
        for log_time, connection, msgtype, msg in sorted(messages, key=lambda m: m[0]):
            writer.write(connection, log_time, serialize(msg, msgtype))
    return truth


def _sensor(recording: dict[str, list[tuple[int, dict[str, Any]]]], sid: str
            ) -> tuple[np.ndarray, dict[str, np.ndarray], dict[str, np.ndarray], dict[str, str]]:
    messages = recording[f"/sensor/{sid}"]
    t = np.concatenate([np.array(d["timestamps_s"], dtype=float) for _, d in messages])
    names = messages[0][1]["channels"]
    channels = {n: np.concatenate([np.array(d["channels"][n], dtype=float)
                                   for _, d in messages]) for n in names}
    valid = {}
    for n in names:
        if any(n in d.get("valid", {}) for _, d in messages):
            valid[n] = np.concatenate([np.array(d.get("valid", {}).get(
                n, [True] * len(d["timestamps_s"])), dtype=bool) for _, d in messages])
    assert all(d["units"] == messages[0][1]["units"] for _, d in messages)
    return t, channels, valid, messages[0][1]["units"]


def _check(truth: _Truth, out: Path, sensors: dict[str, str]) -> dict[str, Any]:
    """Every written value is read back exactly; times are the header stamps less the
    earliest one."""
    recording = read_recording(out / "run.mcap")
    start = min(min(s) for name, s in truth.stamps.items() if name in sensors.values())
    for sid, source in sensors.items():
        t, channels, valid, units = _sensor(recording, sid)
        expected_t = (np.array(truth.stamps[source]) - start) / 1e9
        np.testing.assert_array_equal(t, expected_t)
        kind = {"ft": "geometry_msgs/msg/WrenchStamped", "imu": "sensor_msgs/msg/Imu"}.get(
            source, "biotac_sensors/msg/BioTacHand")
        assert units == {n: u for n, (_, u) in SUPPORTED_TYPES[kind].items()}
        assert set(channels) == set(SUPPORTED_TYPES[kind])
        for name, values in channels.items():
            expected = np.array(truth.channels[source][name], dtype=float)
            assert values.shape == (len(expected_t), *SUPPORTED_TYPES[kind][name][0])
            np.testing.assert_array_equal(values, expected, err_msg=f"{sid}.{name}")
        if source == "imu":
            np.testing.assert_array_equal(valid["orientation_wxyz"],
                                          truth.channels["imu"]["orientation_valid"])
            assert set(valid) == {"orientation_wxyz"}
        else:
            assert valid == {}
        # Blocks of about 0.1 s, never one message for the whole stream.
        spans = [d["timestamps_s"][-1] - d["timestamps_s"][0]
                 for _, d in recording[f"/sensor/{sid}"]]
        assert len(spans) >= 2 and max(spans) < 0.25
    return recording


@pytest.mark.parametrize("ros", ["ros1", "ros2-sqlite3", "ros2-mcap"])
def test_bag_round_trips_exactly(tmp_path: Path, ros: str) -> None:
    bag = tmp_path / ("in.bag" if ros == "ros1" else "in")
    truth = _write_bag(bag, ros)
    out = tmp_path / "out"
    result = import_bag(bag, [parse_map("/ft/wrench=ft"), parse_map("/imu/data=imu"),
                              parse_map("/biotac_pub=tip")], out)
    truth.stamps["tip"], truth.channels["tip"] = truth.stamps["tip1"], truth.channels["tip1"]
    _check(truth, out, {"ft": "ft", "imu": "imu", "tip": "tip"})
    start = EPOCH_S * 1_000_000_000 + 123_456_789
    assert result.start_time_ns == start
    record = json.loads((out / "import.json").read_text())
    assert record["status"] == "ok" and record["start_time_ns"] == start
    assert sorted(record["files"]) == ["run.mcap"]
    assert record["sensors"]["imu"]["samples"] == 60
    from mcap.reader import make_reader

    with open(out / "run.mcap", "rb") as stream:
        metadata = {m.name: m.metadata for m in make_reader(stream).iter_metadata()}
    assert metadata["hapticframe"]["start_time_ns"] == str(start)
    assert metadata["hapticframe"]["start_utc"] == "2023-11-14T22:13:20.123456789Z"


def test_biotac_definitions_match_the_driver(tmp_path: Path) -> None:
    """The text definitions give the driver's own ROS 1 md5sum, so its bags read."""
    store = _store(ros1=True)
    assert store.generate_msgdef("biotac_sensors/msg/BioTacHand")[1] == (
        "d96f900cbfb096d61de125081e11dcab")


def test_a_finger_of_a_hand_by_position_or_serial(tmp_path: Path, capsys: Any) -> None:
    bag = tmp_path / "hand.bag"
    truth = _write_bag(bag, "ros1", n=12, fingers=3)
    out = tmp_path / "out"
    assert main(["import-bag", str(bag), "--map", "/biotac_pub:2=index",
                 "--map", "/biotac_pub:BT0002=ring", "--out", str(out)]) == 0
    recording = read_recording(out / "run.mcap")
    for sid, source in (("index", "tip2"), ("ring", "tip3")):
        _, channels, _, _ = _sensor(recording, sid)
        np.testing.assert_array_equal(channels["electrodes"],
                                      np.array(truth.channels[source]["electrodes"], float))
    assert "/biotac_pub (biotac_sensors/msg/BioTacHand) -> /sensor/index: 12 samples" in (
        capsys.readouterr().out)
    # Without a finger, a hand of three is ambiguous: exit 2 listing the fingers.
    assert main(["import-bag", str(bag), "--map", "/biotac_pub=tip",
                 "--out", str(tmp_path / "o2")]) == 2
    err = capsys.readouterr().err
    assert "3 fingers" in err and "1 (BT0000), 2 (BT0001), 3 (BT0002)" in err
    assert not (tmp_path / "o2").exists()  # nothing left behind
    assert main(["import-bag", str(bag), "--map", "/biotac_pub:9=tip",
                 "--out", str(tmp_path / "o3")]) == 2
    assert "holds finger '9'" in capsys.readouterr().err


def test_unstamped_and_repeated_stamps(tmp_path: Path) -> None:
    """A header stamp of 0 takes the bag's receive time; a repeated stamp is dropped."""
    store = _store(ros1=True)
    bag = tmp_path / "odd.bag"
    rng = np.random.default_rng(3)
    forces = rng.normal(size=(4, 3))
    stamps = [5_000_000_000, 0, 5_000_000_000, 5_020_000_000]  # header stamps
    with Writer1(bag) as writer:
        conn = writer.add_connection("/w", "geometry_msgs/msg/WrenchStamped", typestore=store)
        for k, (stamp, force) in enumerate(zip(stamps, forces, strict=True)):
            msg = _wrench(store, _header(store, stamp, True), force, -force)
            writer.write(conn, 5_010_000_000 + k, store.serialize_ros1(
                msg, "geometry_msgs/msg/WrenchStamped"))
    result = import_bag(bag, [parse_map("w=ft")], tmp_path / "out")
    assert result.sensors["ft"]["dropped_repeated_stamp"] == 1
    assert result.sensors["ft"]["stamped_by_receive_time"] == 1
    t, channels, _, _ = _sensor(read_recording(tmp_path / "out" / "run.mcap"), "ft")
    np.testing.assert_array_equal(t, [0.0, 0.010000001, 0.02])
    np.testing.assert_array_equal(channels["force_n"], forces[[0, 1, 3]])
    np.testing.assert_array_equal(channels["torque_nm"], -forces[[0, 1, 3]])


@pytest.fixture(scope="module")
def small_bag(tmp_path_factory: pytest.TempPathFactory) -> Path:
    bag = tmp_path_factory.mktemp("bag") / "small.bag"
    _write_bag(bag, "ros1", n=3)
    return bag


@pytest.mark.parametrize(("maps", "message"), [
    (["/nope=ft"], "has no topic '/nope'; its topics: /biotac_pub "
                   "(biotac_sensors/msg/BioTacHand, 3 messages), /ft/wrench"),
    (["/rosout_like=ft"], "holds std_msgs/msg/String, which import-bag does not read"),
    (["/ft/wrench"], "expected TOPIC=SENSOR_ID"),
    (["/ft/wrench=9lives"], "is not an id"),
    (["/ft/wrench=a", "/imu/data=a"], "sensor id 'a' is given twice"),
    (["/ft/wrench=a", "/ft/wrench=b"], "topic /ft/wrench is mapped twice"),
    (["/ft/wrench:1=a"], "a finger (':1') is for BioTac hand topics"),
    ([], "give at least one --map"),
])
def test_bad_maps_exit_2_naming_the_problem(small_bag: Path, tmp_path: Path, capsys: Any,
                                            maps: list[str], message: str) -> None:
    args = ["import-bag", str(small_bag), "--out", str(tmp_path / "out")]
    for m in maps:
        args += ["--map", m]
    assert main(args) == 2
    err = capsys.readouterr().err
    assert message in err and "Traceback" not in err
    assert not (tmp_path / "out").exists()


def test_empty_and_missing_bags_exit_2(tmp_path: Path, capsys: Any) -> None:
    store = _store(ros1=True)
    empty = tmp_path / "empty.bag"
    with Writer1(empty) as writer:
        writer.add_connection("/ft/wrench", "geometry_msgs/msg/WrenchStamped", typestore=store)
    assert main(["import-bag", str(empty), "--map", "/ft/wrench=ft",
                 "--out", str(tmp_path / "o")]) == 2
    assert "holds no messages; its topics: /ft/wrench (geometry_msgs/msg/WrenchStamped, 0 " \
        "messages)" in capsys.readouterr().err
    assert main(["import-bag", str(tmp_path / "none.bag"), "--map", "/a=b",
                 "--out", str(tmp_path / "o")]) == 2
    assert "no such bag" in capsys.readouterr().err
    junk = tmp_path / "junk.bag"
    junk.write_bytes(b"not a bag at all")
    assert main(["import-bag", str(junk), "--map", "/a=b", "--out", str(tmp_path / "o")]) == 2
    assert "cannot be read as a ROS 1 bag" in capsys.readouterr().err


def test_out_holds_an_import_overwrite_replaces_it(small_bag: Path, tmp_path: Path) -> None:
    out = tmp_path / "out"
    args = ["import-bag", str(small_bag), "--map", "/ft/wrench=ft", "--out", str(out)]
    assert main(args) == 0
    assert main(args) == 2  # an import is there
    assert main([*args[:-2], "--map", "/imu/data=imu", "--out", str(out), "--overwrite"]) == 0
    assert set(read_recording(out / "run.mcap")) == {"/sensor/ft", "/sensor/imu"}


def test_parse_map() -> None:
    assert parse_map("imu/data=imu").topic == "/imu/data"
    m = parse_map("/biotac_pub:BT0001=tip")
    assert (m.topic, m.finger, m.sensor_id, str(m)) == (
        "/biotac_pub", "BT0001", "tip", "/biotac_pub:BT0001=tip")
    with pytest.raises(UsageError):
        parse_map("=x")


def _message_records_at(blob: bytes) -> list[int]:
    """Where the message data records (op 0x02) of the first chunk of a ROS 1 bag lie: after
    the magic line, the bag header record (its data is padding) and the chunk record's
    header, among the chunk's connection and message records."""
    def record(at: int) -> tuple[bytes, int]:  # (header, where the next record starts)
        header_len = int.from_bytes(blob[at:at + 4], "little")
        header = blob[at + 4:at + 4 + header_len]
        data_at = at + 4 + header_len
        return header, data_at + 4 + int.from_bytes(blob[data_at:data_at + 4], "little")

    _, at = record(len(b"#ROSBAG V2.0\n"))  # the bag header record
    header, end = record(at)
    at += 4 + len(header) + 4  # into the chunk record's data
    found = []
    while at < end:
        header, following = record(at)
        if b"op=\x02" in header:
            found.append(at)
        at = following
    return found


def test_a_bag_damaged_inside_a_chunk_exits_2(small_bag: Path, tmp_path: Path,
                                              capsys: Any) -> None:
    # Issue 26 (found by `hapticframe bench fuzz`, family "bags"): a bag whose index reads
    # but whose chunk is damaged gave "internal error: ReaderError" while reading messages.
    blob = bytearray(small_bag.read_bytes())
    records = _message_records_at(bytes(blob))
    assert records
    for at in records:  # each message's first header field longer than its header
        blob[at + 4:at + 8] = (0x7FFFFFF0).to_bytes(4, "little")
    bag = tmp_path / "damaged.bag"
    bag.write_bytes(bytes(blob))
    assert main(["import-bag", str(bag), "--map", "/ft/wrench=ft",
                 "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    assert "internal error" not in err and f"{bag} is damaged" in err
    assert not (tmp_path / "out" / "run.mcap").exists()
