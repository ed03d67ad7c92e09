"""``hapticframe import-bag``: ROS 1 and ROS 2 bags as a recording the ``recording`` source reads.

A bag (a ROS 1 ``.bag`` file, or a ROS 2 bag directory with sqlite3 or mcap storage) is
read with ``rosbags`` (pure Python, the ``bags`` extra). Each ``--map TOPIC=SENSOR_ID``
turns one topic into the ``/sensor/SENSOR_ID`` channel of ``DIR/run.mcap``:
``hapticframe.SampleBatch`` messages of one or two blocks of
:data:`~hapticframe.record._recording.BLOCK_S` of stamps (0.1-0.2 s, docs/recording.md),
written by :meth:`RunRecording.samples <hapticframe.record._recording.RunRecording.samples>`
exactly as a run writes its sensors.

Message types and the channels they become (names and units those of the bundled sensors
that measure the same, so that a pipeline built for them reads an imported bag):

==================================  =====================================================
type                                channels (shape, unit)
==================================  =====================================================
``geometry_msgs/WrenchStamped``     ``force_n`` (3, N), ``torque_nm`` (3, N·m): as robotiq
``sensor_msgs/Imu``                 ``angular_velocity_rad_per_s`` (3, rad/s),
                                    ``acceleration_m_per_s2`` (3, m/s^2; ROS's
                                    ``linear_acceleration`` holds gravity, REP 145),
                                    ``orientation_wxyz`` (4, 1): as bno055
``biotac_sensors/BioTacHand``       ``pdc``, ``tac``, ``tdc`` (), ``pac`` (22,),
                                    ``electrodes`` (19,), all ``count``: as biotac
==================================  =====================================================

An Imu field whose covariance starts with -1 ("no estimate", as ``sensor_msgs/Imu``
defines) is recorded as invalid for that sample. A BioTac hand message holds every finger
of the hand; ``TOPIC:FINGER=SENSOR_ID`` picks one by its ``bt_position`` or ``bt_serial``
(needed when the hand has more than one).

Rates: each channel's nominal rate is recorded (``rates_hz``), as a run records its
sensors' declared rates, so that the ``recording`` sensor declares it on replay: a BioTac
hand's is the BioTac's frame rate (100 Hz); a wrench's or an IMU's is the stream's mean
rate, samples less one over the span of their stamps (the median period would overstate a
jittery stream's rate). ``import.json`` gives each sensor's ``rate_hz`` and ``rate_from``.

Time: a message's header stamp (a stamp of 0, never set by its publisher, is replaced by
the bag's receive time) minus the earliest stamp of every imported message gives
``timestamps_s``; that earliest stamp is in the recording's ``hapticframe`` metadata
(``start_time_ns``, ``start_utc``). A channel's samples are sorted by stamp; a sample whose
stamp repeats an earlier one is dropped (counted in ``import.json``).
"""

from __future__ import annotations

import json
import re
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from datetime import datetime, timezone
from pathlib import Path
from typing import Any

import numpy as np

from hapticframe._errors import UsageError
from hapticframe.run._channels import SENSOR
from hapticframe.run._results import OutputDir, environment

__all__ = [
    "BIOTAC_MSGS",
    "SUPPORTED_TYPES",
    "BagImport",
    "TopicMap",
    "biotac_types",
    "describe",
    "import_bag",
    "parse_map",
]

#: Message definitions of the ``biotac_sensors`` ROS package (the BioTac driver's), as
#: ``rosbags.typesys.get_types_from_msg`` reads them; ROS 1's md5sum of BioTacHand is
#: d96f900cbfb096d61de125081e11dcab.
BIOTAC_MSGS: Mapping[str, str] = {
    "biotac_sensors/msg/BioTacData": (
        "string bt_serial\n"
        "uint16 bt_position\n"
        "uint16 tdc_data\n"
        "uint16 tac_data\n"
        "uint16 pdc_data\n"
        "uint16[22] pac_data\n"
        "uint16[19] electrode_data\n"
    ),
    "biotac_sensors/msg/BioTacTime": (
        "time frame_start_time\n"
        "time frame_end_time\n"
        "uint32 tdc_ns_offset\n"
        "uint32 tac_ns_offset\n"
        "uint32 pdc_ns_offset\n"
        "uint32[22] pac_ns_offset\n"
        "uint32[19] electrode_ns_offset\n"
    ),
    "biotac_sensors/msg/BioTacHand": (
        "Header header\n"
        "string hand_id\n"
        "biotac_sensors/BioTacData[] bt_data\n"
        "biotac_sensors/BioTacTime bt_time\n"
    ),
}

_WRENCH = "geometry_msgs/msg/WrenchStamped"
_IMU = "sensor_msgs/msg/Imu"
_BIOTAC = "biotac_sensors/msg/BioTacHand"
#: The channels (shape, unit) each supported message type becomes.
SUPPORTED_TYPES: Mapping[str, Mapping[str, tuple[tuple[int, ...], str]]] = {
    _WRENCH: {"force_n": ((3,), "N"), "torque_nm": ((3,), "N·m")},
    _IMU: {"angular_velocity_rad_per_s": ((3,), "rad/s"),
           "acceleration_m_per_s2": ((3,), "m/s^2"),
           "orientation_wxyz": ((4,), "1")},
    _BIOTAC: {"pac": ((22,), "count"), "pdc": ((), "count"), "tac": ((), "count"),
              "tdc": ((), "count"), "electrodes": ((19,), "count")},
}

# A ROS name holds no ':' or '=': TOPIC[:FINGER]=SENSOR_ID splits unambiguously.
_MAP = re.compile(r"^(?P<topic>[^:=]+)(?::(?P<finger>[^=]+))?=(?P<sensor>.*)$")


@dataclass(frozen=True)
class TopicMap:
    """One ``--map``: a bag topic (and BioTac finger) to a sensor id."""

    topic: str
    sensor_id: str
    #: A BioTac finger's ``bt_position`` or ``bt_serial`` ("" when not given).
    finger: str = ""

    def __str__(self) -> str:
        return f"{self.topic}{':' + self.finger if self.finger else ''}={self.sensor_id}"


def parse_map(text: str) -> TopicMap:
    """``TOPIC=SENSOR_ID`` or ``TOPIC:FINGER=SENSOR_ID`` (UsageError otherwise)."""
    from hapticframe._config._model import ID_PATTERN

    match = _MAP.match(text.strip())
    if match is None:
        raise UsageError(f"--map {text!r}: expected TOPIC=SENSOR_ID (or TOPIC:FINGER=SENSOR_ID "
                         "for one finger of a BioTac hand), e.g. --map /ft_sensor/wrench=ft")
    topic, sensor = match["topic"].strip(), match["sensor"].strip()
    if not re.match(ID_PATTERN, sensor):
        raise UsageError(f"--map {text!r}: sensor id {sensor!r} is not an id (a letter "
                         "followed by at most 63 letters, digits, '-' or '_')")
    return TopicMap(topic if topic.startswith("/") else "/" + topic, sensor,
                    (match["finger"] or "").strip())


def biotac_types() -> dict[str, Any]:
    """The ``biotac_sensors`` types, for a ``rosbags`` typestore's ``register``."""
    from rosbags.typesys import get_types_from_msg

    types: dict[str, Any] = {}
    for name, text in BIOTAC_MSGS.items():
        types.update(get_types_from_msg(text, name))
    return types


def _typestore(ros1: bool) -> Any:
    """The types of a bag that embeds none (older ROS 2 sqlite3 bags): ROS's standard
    messages and the BioTac driver's."""
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS1_NOETIC if ros1 else Stores.LATEST)
    store.register(biotac_types())
    return store


# --- messages to rows ------------------------------------------------------------------------

Row = dict[str, np.ndarray]
#: A converter: message → (channel values, channel validity), or None to skip the message.
Converter = Callable[[Any], "tuple[Row, dict[str, bool]] | None"]


def _xyz(vector: Any) -> np.ndarray:
    return np.array([vector.x, vector.y, vector.z], dtype=np.float64)


def _wrench(msg: Any) -> tuple[Row, dict[str, bool]]:
    return {"force_n": _xyz(msg.wrench.force), "torque_nm": _xyz(msg.wrench.torque)}, {}


def _imu(msg: Any) -> tuple[Row, dict[str, bool]]:
    q = msg.orientation
    row = {"angular_velocity_rad_per_s": _xyz(msg.angular_velocity),
           "acceleration_m_per_s2": _xyz(msg.linear_acceleration),
           "orientation_wxyz": np.array([q.w, q.x, q.y, q.z], dtype=np.float64)}
    # sensor_msgs/Imu: a covariance whose first element is -1 means "no estimate".
    valid = {"angular_velocity_rad_per_s": msg.angular_velocity_covariance[0] != -1,
             "acceleration_m_per_s2": msg.linear_acceleration_covariance[0] != -1,
             "orientation_wxyz": msg.orientation_covariance[0] != -1}
    return row, {k: bool(v) for k, v in valid.items()}


def _biotac(finger: str, topic: str) -> Converter:
    def convert(msg: Any) -> tuple[Row, dict[str, bool]] | None:
        fingers = list(msg.bt_data)
        if finger:
            fingers = [f for f in fingers if finger in (str(f.bt_position), f.bt_serial)]
        elif len(fingers) > 1:
            seen = ", ".join(f"{f.bt_position} ({f.bt_serial})" for f in msg.bt_data)
            raise UsageError(
                f"--map {topic}: its BioTac hand messages hold {len(fingers)} fingers "
                f"(bt_position (bt_serial): {seen}); pick one with {topic}:POSITION=SENSOR_ID "
                f"or {topic}:SERIAL=SENSOR_ID, one --map per finger")
        if not fingers:
            return None
        f = fingers[0]
        return {"pac": np.asarray(f.pac_data, dtype=np.float64),
                "pdc": np.array(float(f.pdc_data)), "tac": np.array(float(f.tac_data)),
                "tdc": np.array(float(f.tdc_data)),
                "electrodes": np.asarray(f.electrode_data, dtype=np.float64)}, {}

    return convert


# --- the import ------------------------------------------------------------------------------


@dataclass
class _Stream:
    """One mapped topic while the bag is read."""

    map: TopicMap
    msgtype: str
    convert: Converter
    stamps_ns: list[int] = field(default_factory=list)
    rows: dict[str, list[np.ndarray]] = field(default_factory=dict)
    valid: dict[str, list[bool]] = field(default_factory=dict)
    messages: int = 0
    unstamped: int = 0
    skipped: int = 0
    repeated: int = 0

    def add(self, msg: Any, log_time_ns: int) -> None:
        self.messages += 1
        converted = self.convert(msg)
        if converted is None:
            self.skipped += 1
            return
        row, flags = converted
        stamp = msg.header.stamp
        stamp_ns = int(stamp.sec) * 1_000_000_000 + int(stamp.nanosec)
        if stamp_ns == 0:
            self.unstamped += 1
            stamp_ns = int(log_time_ns)
        self.stamps_ns.append(stamp_ns)
        for name, value in row.items():
            self.rows.setdefault(name, []).append(value)
        for name, ok in flags.items():
            self.valid.setdefault(name, []).append(ok)


@dataclass
class BagImport:
    """What :func:`import_bag` wrote: per sensor id, its topic, type and counts."""

    bag: Path
    out: Path
    start_time_ns: int
    duration_s: float
    sensors: dict[str, dict[str, Any]]
    messages: int


def _listing(topics: Mapping[str, Any]) -> str:
    if not topics:
        return "the bag holds no topics"
    return "its topics: " + ", ".join(
        f"{name} ({info.msgtype or 'several types'}, {info.msgcount} messages)"
        for name, info in sorted(topics.items()))


def _open_reader(bag: Path) -> Any:
    from rosbags.highlevel import AnyReader, AnyReaderError

    if not bag.exists():
        raise UsageError(f"{bag}: no such bag (give a ROS 1 .bag file or a ROS 2 bag "
                         "directory)")
    ros1 = bag.is_file() and bag.suffix == ".bag"
    if bag.is_file() and not ros1:
        raise UsageError(f"{bag} is neither a ROS 1 .bag file nor a ROS 2 bag directory "
                         "(the folder holding metadata.yaml)")
    try:
        reader = AnyReader([bag], default_typestore=_typestore(ros1))
        reader.open()
    except (AnyReaderError, OSError, ValueError, KeyError) as exc:
        raise UsageError(f"{bag} cannot be read as a ROS {'1' if ros1 else '2'} bag: "
                         f"{exc}") from exc
    return reader


def _streams(bag: Path, reader: Any, maps: Sequence[TopicMap]) -> list[_Stream]:
    topics = reader.topics
    if not topics or not reader.message_count:
        raise UsageError(f"{bag} holds no messages; {_listing(topics)}")
    streams = []
    for m in maps:
        info = topics.get(m.topic)
        if info is None:
            raise UsageError(f"--map {m}: {bag} has no topic {m.topic!r}; {_listing(topics)}")
        if info.msgtype not in SUPPORTED_TYPES:
            raise UsageError(
                f"--map {m}: topic {m.topic} holds {info.msgtype or 'several types'}, which "
                f"import-bag does not read (it reads {', '.join(sorted(SUPPORTED_TYPES))}); "
                f"{_listing(topics)}")
        if not info.msgcount:
            raise UsageError(f"--map {m}: topic {m.topic} holds no messages; {_listing(topics)}")
        if m.finger and info.msgtype != _BIOTAC:
            raise UsageError(f"--map {m}: a finger (':{m.finger}') is for BioTac hand "
                             f"topics; {m.topic} holds {info.msgtype}")
        convert: Converter = {_WRENCH: _wrench, _IMU: _imu}.get(info.msgtype) or _biotac(
            m.finger, m.topic)
        streams.append(_Stream(m, info.msgtype, convert))
    return streams


def _check_maps(maps: Sequence[TopicMap]) -> None:
    if not maps:
        raise UsageError("give at least one --map TOPIC=SENSOR_ID")
    ids = [m.sensor_id for m in maps]
    twice = sorted({i for i in ids if ids.count(i) > 1})
    if twice:
        raise UsageError(f"--map: sensor id {twice[0]!r} is given twice; each sensor takes "
                         "one topic")
    keys = [(m.topic, m.finger) for m in maps]
    again = sorted({k for k in keys if keys.count(k) > 1})
    if again:
        raise UsageError(f"--map: topic {again[0][0]} is mapped twice"
                         + (f" (finger {again[0][1]})" if again[0][1] else ""))


def _arrays(stream: _Stream, start_ns: int) -> tuple[np.ndarray, dict[str, np.ndarray],
                                                      dict[str, np.ndarray]]:
    """A stream's times (s from ``start_ns``), channels and validity, sorted by stamp with
    repeated stamps dropped."""
    stamps = np.array(stream.stamps_ns, dtype=np.int64)
    order = np.argsort(stamps, kind="stable")
    stamps = stamps[order]
    keep = np.ones(stamps.size, dtype=bool)
    keep[1:] = stamps[1:] != stamps[:-1]
    stream.repeated = int((~keep).sum())
    rows = order[keep]
    # Integer nanoseconds first, then seconds: float64 keeps a bag's relative times exact
    # to the nanosecond for some 100 days.
    t = (stamps[keep] - start_ns).astype(np.float64) / 1e9
    channels = {name: np.stack(values)[rows] for name, values in stream.rows.items()}
    valid = {name: np.array(flags, dtype=bool)[rows] for name, flags in stream.valid.items()}
    # Only a channel with an invalid sample carries flags (missing means valid).
    return t, channels, {name: v for name, v in valid.items() if not v.all()}


#: The BioTac's frame rate: its driver publishes one hand message per frame.
_BIOTAC_RATE_HZ = 100.0


def nominal_rate(msgtype: str, t: np.ndarray) -> tuple[float | None, str]:
    """A stream's nominal rate (Hz) and where it comes from: the BioTac's frame rate, else
    the mean rate of the stamps (None for a single sample)."""
    if msgtype == _BIOTAC:
        return _BIOTAC_RATE_HZ, "the BioTac frame rate"
    span = float(t[-1] - t[0]) if t.size > 1 else 0.0
    if span <= 0:
        return None, "a single sample: none"
    return (t.size - 1) / span, "mean rate of the stamps"


def import_bag(bag: str | Path, maps: Sequence[TopicMap], out_dir: str | Path, *,
               overwrite: bool = False, min_free_bytes: int | None = None) -> BagImport:
    """Read ``bag`` and write ``out_dir/run.mcap`` (and ``import.json``, the import's record).

    Raises
    ------
    UsageError
        ``rosbags`` is missing; the bag cannot be read, holds no messages, or lacks a
        mapped topic; a topic holds a type not in :data:`SUPPORTED_TYPES` or no messages;
        ``out_dir`` holds results ``overwrite`` may not replace (exit status 2).
    OutputError
        ``out_dir`` cannot be written (exit status 1).
    """
    try:
        import rosbags  # noqa: F401
    except ImportError as exc:
        raise UsageError("import-bag needs rosbags: pip install 'hapticframe[bags]'") from exc
    bag = Path(bag)
    _check_maps(maps)
    reader = _open_reader(bag)
    directory: OutputDir | None = None
    try:
        streams = _streams(bag, reader, maps)
        # The bag and the maps are checked: only now may --overwrite clear DIR.
        directory = OutputDir.prepare(out_dir, record="import.json", command="bag import",
                                      overwrite=overwrite, min_free=min_free_bytes)
        directory.begin({"command": "import-bag", "bag": str(bag),
                         "maps": [str(m) for m in maps], "versions": environment()})
        _read(bag, reader, streams)
    except BaseException:
        if directory is not None:
            directory.discard()
        raise
    finally:
        reader.close()
    assert directory is not None  # prepared, or the reading raised
    try:
        return _write(bag, streams, directory)
    except BaseException:
        directory.discard()
        raise
    finally:
        directory.release()


def _utc(stamp_ns: int) -> str:
    """An absolute time to the nanosecond (a float of seconds since 1970 holds microseconds)."""
    seconds, ns = divmod(stamp_ns, 1_000_000_000)
    return f"{datetime.fromtimestamp(seconds, timezone.utc):%Y-%m-%dT%H:%M:%S}.{ns:09d}Z"


def _damage_errors() -> tuple[type[BaseException], ...]:
    """What reading the messages of a damaged bag raises (rosbags' reader errors, and what
    deserializing cut or flipped bytes raises)."""
    import sqlite3
    import struct

    from rosbags.highlevel import AnyReaderError
    from rosbags.rosbag1 import ReaderError as Ros1ReaderError
    from rosbags.rosbag2 import ReaderError as Ros2ReaderError

    # rosbags checks a ROS 1 index entry against its message's header with an assert.
    return (AnyReaderError, Ros1ReaderError, Ros2ReaderError, sqlite3.DatabaseError,
            struct.error, ValueError, IndexError, KeyError, UnicodeDecodeError, OSError,
            AssertionError)


def _read(bag: Path, reader: Any, streams: Sequence[_Stream]) -> None:
    try:
        _read_messages(reader, streams)
    except _damage_errors() as exc:
        raise UsageError(f"{bag} is damaged: its messages cannot be read "
                         f"({type(exc).__name__}: {exc}); nothing was imported") from exc


def _read_messages(reader: Any, streams: Sequence[_Stream]) -> None:
    # Two fingers of one hand are two streams of one topic.
    by_connection: dict[tuple[int, int], list[_Stream]] = {}
    wanted = {}
    for stream in streams:
        for connection in reader.topics[stream.map.topic].connections:
            key = (connection.id, id(connection.owner))
            by_connection.setdefault(key, []).append(stream)
            wanted[key] = connection
    for connection, log_time_ns, raw in reader.messages(connections=list(wanted.values())):
        msg = reader.deserialize(raw, connection.msgtype)
        for stream in by_connection[connection.id, id(connection.owner)]:
            stream.add(msg, log_time_ns)
    for stream in streams:
        if not stream.stamps_ns:
            raise UsageError(f"--map {stream.map}: no message of {stream.map.topic} holds "
                             f"finger {stream.map.finger!r} (give a bt_position or bt_serial "
                             "of the hand)")


def _write(bag: Path, streams: Sequence[_Stream], directory: OutputDir) -> BagImport:
    from hapticframe.kinds import SampleBatch
    from hapticframe.record._recording import BLOCK_S, RECORDING, RunRecording

    start_ns = min(min(s.stamps_ns) for s in streams)
    data = {s.map.sensor_id: _arrays(s, start_ns) for s in streams}
    end_s = max(float(t[-1]) for t, _, _ in data.values())
    units = {s.map.sensor_id: {n: unit for n, (_, unit) in SUPPORTED_TYPES[s.msgtype].items()}
             for s in streams}
    start_utc = _utc(start_ns)
    rates = {s.map.sensor_id: nominal_rate(s.msgtype, data[s.map.sensor_id][0])
             for s in streams}
    sensors = {s.map.sensor_id: {
        "topic": s.map.topic, "type": s.msgtype,
        "rate_hz": rates[s.map.sensor_id][0], "rate_from": rates[s.map.sensor_id][1],
        **({"finger": s.map.finger} if s.map.finger else {}),
        "messages": s.messages, "samples": int(data[s.map.sensor_id][0].size),
        "skipped_without_finger": s.skipped, "dropped_repeated_stamp": s.repeated,
        "stamped_by_receive_time": s.unstamped} for s in streams}
    record: dict[str, Any] = {
        "command": "import-bag", "bag": str(bag), "start_time_ns": start_ns,
        "start_utc": start_utc, "duration_s": end_s, "sensors": sensors,
        "versions": environment()}
    recording = RunRecording(directory.staging / RECORDING, {
        "name": f"import of {bag.name}", "source": "import-bag", "bag": str(bag),
        "start_time_ns": str(start_ns), "start_utc": start_utc,
        "sensors": json.dumps(sensors, sort_keys=True)})
    try:
        # Block by block in time order over every sensor, as a run writes them.
        windows = np.unique(np.concatenate(
            [np.floor(t / BLOCK_S).astype(np.int64) for t, _, _ in data.values()]))
        for window in windows:
            lo, hi = window * BLOCK_S, (window + 1) * BLOCK_S
            for sid, (t, channels, valid) in data.items():
                a, b = np.searchsorted(t, [lo, hi])
                if a == b:
                    continue
                rate = rates[sid][0]
                recording.samples("sensor", sid, SampleBatch(
                    t[a:b], {n: v[a:b] for n, v in channels.items()},
                    {n: v[a:b] for n, v in valid.items()}), units[sid],
                    None if rate is None else dict.fromkeys(channels, rate))
    finally:
        recording.close()
    files = directory.commit(record)
    directory.finish({**record, "status": "ok"}, files)
    return BagImport(bag, directory.path, start_ns, end_s, sensors, recording.messages)


def describe(result: BagImport) -> list[str]:
    """The lines ``hapticframe import-bag`` prints: each sensor's samples, then the file."""
    lines = []
    for sid, s in sorted(result.sensors.items()):
        notes = []
        if s["dropped_repeated_stamp"]:
            notes.append(f"{s['dropped_repeated_stamp']} dropped: stamp repeated")
        if s["stamped_by_receive_time"]:
            notes.append(f"{s['stamped_by_receive_time']} without a header stamp: the bag's "
                         "receive time used")
        if s["skipped_without_finger"]:
            notes.append(f"{s['skipped_without_finger']} without finger {s.get('finger')}")
        lines.append(f"  {s['topic']} ({s['type']}) -> {SENSOR.topic(sid)}: {s['samples']} samples"
                     + (f" ({'; '.join(notes)})" if notes else ""))
    lines.append(f"wrote {result.out / 'run.mcap'}: {result.messages} messages, "
                 f"{result.duration_s:.3f} s from {_utc(result.start_time_ns)}")
    return lines
