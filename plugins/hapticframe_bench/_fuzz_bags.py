"""The ``bags`` family of ``hapticframe bench fuzz``: damaged ROS bags through ``import-bag``.

Three small bags are written once with rosbags (a ROS 1 ``.bag``, ROS 2 bags in sqlite3 and
in mcap storage; 100 Hz ``WrenchStamped`` and 200 Hz ``Imu`` for a second, and a
``std_msgs/String`` topic), then a copy is damaged one way — cut at a random byte, bits
flipped, replaced by junk, emptied, its ``metadata.yaml`` removed or garbled or its counts
changed, its storage file removed — and imported with ``--map`` options that are right or
not (a topic the bag lacks, a type import-bag does not read, a malformed or repeated map).
The bag itself must stay as it was; an import that ends with exit 0 must leave a
``run.mcap`` and a strict ``import.json`` with samples in it.
"""

from __future__ import annotations

import json
import shutil
import time
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from hapticframe_bench._fuzz_common import (
    Case,
    Outcome,
    classify,
    compare_snapshots,
    hapticframe_command,
    json_has_null_number,
    snapshot,
)

__all__ = ["DAMAGES", "FORMATS", "check_bag_case", "generate_bag_cases", "write_bags"]

FORMATS = ("ros1", "ros2-sqlite3", "ros2-mcap")
DAMAGES = ("none", "truncate", "flip", "junk", "empty", "no_metadata", "garbled_metadata",
           "metadata_counts", "no_storage")
MAPS: tuple[tuple[str, ...], ...] = (
    ("/ft/wrench=ft",), ("/imu/data=imu",), ("/ft/wrench=ft", "/imu/data=imu"),
    ("/missing=ft",), ("/text=ft",), ("x",), ("/ft/wrench=ft", "/imu/data=ft"),
    ("/ft/wrench=",), ("/ft/wrench:2=ft",))
_EPOCH_NS = 1_700_000_000 * 1_000_000_000


def write_bags(root: Path, seed: int = 0) -> dict[str, Path]:
    """The three small bags, written into ``root`` (needs rosbags: ``hapticframe[bags]``)."""
    from rosbags.rosbag1 import Writer as Writer1
    from rosbags.rosbag2 import StoragePlugin
    from rosbags.rosbag2 import Writer as Writer2
    from rosbags.typesys import Stores, get_typestore

    rng = np.random.default_rng(seed)
    root.mkdir(parents=True, exist_ok=True)
    bags = {}
    for fmt in FORMATS:
        ros1 = fmt == "ros1"
        store = get_typestore(Stores.ROS1_NOETIC if ros1 else Stores.ROS2_HUMBLE)
        path = root / ("session.bag" if ros1 else f"session-{fmt}")
        writer: Any = Writer1(path) if ros1 else Writer2(
            path, version=9, storage_plugin=StoragePlugin.MCAP if fmt == "ros2-mcap"
            else StoragePlugin.SQLITE3)
        _fill(writer, store, ros1, rng)
        bags[fmt] = path
    return bags


def _fill(writer: Any, store: Any, ros1: bool, rng: np.random.Generator) -> None:
    t = store.types
    serialize = store.serialize_ros1 if ros1 else store.serialize_cdr

    def header(stamp: int) -> Any:
        time_ = t["builtin_interfaces/msg/Time"](sec=stamp // 10**9, nanosec=stamp % 10**9)
        return (t["std_msgs/msg/Header"](seq=0, stamp=time_, frame_id="tip") if ros1
                else t["std_msgs/msg/Header"](stamp=time_, frame_id="tip"))

    def vector(v: Any) -> Any:
        return t["geometry_msgs/msg/Vector3"](x=float(v[0]), y=float(v[1]), z=float(v[2]))

    with writer:
        wrench = writer.add_connection("/ft/wrench", "geometry_msgs/msg/WrenchStamped",
                                       typestore=store)
        imu = writer.add_connection("/imu/data", "sensor_msgs/msg/Imu", typestore=store)
        text = writer.add_connection("/text", "std_msgs/msg/String", typestore=store)
        zero = np.zeros(9)
        for k in range(200):
            stamp = _EPOCH_NS + k * 5_000_000
            if k % 2 == 0:
                msg = t["geometry_msgs/msg/WrenchStamped"](
                    header=header(stamp), wrench=t["geometry_msgs/msg/Wrench"](
                        force=vector(rng.normal(size=3)),
                        torque=vector(rng.normal(size=3))))
                writer.write(wrench, stamp, serialize(msg, msg.__msgtype__))
            q = rng.normal(size=4)
            q /= np.linalg.norm(q)
            msg = t["sensor_msgs/msg/Imu"](
                header=header(stamp), orientation=t["geometry_msgs/msg/Quaternion"](
                    x=q[0], y=q[1], z=q[2], w=q[3]),
                orientation_covariance=zero, angular_velocity=vector(rng.normal(size=3)),
                angular_velocity_covariance=zero,
                linear_acceleration=vector(rng.normal(size=3)),
                linear_acceleration_covariance=zero)
            writer.write(imu, stamp, serialize(msg, msg.__msgtype__))
            if k % 50 == 0:
                msg = t["std_msgs/msg/String"](data=f"note {k}")
                writer.write(text, stamp, serialize(msg, msg.__msgtype__))


def generate_bag_cases(count: int, seed: int) -> list[Case]:
    """``count`` cases: each damage in turn, the format and the maps drawn (seeded)."""
    rng = np.random.default_rng(seed)
    cases = []
    for k in range(count):
        damage = DAMAGES[k % len(DAMAGES)]
        fmt = FORMATS[int(rng.integers(len(FORMATS)))]
        maps = MAPS[int(rng.integers(len(MAPS)))] if rng.random() < 0.4 else MAPS[2]
        cases.append(Case("bags", damage, f"{fmt} {damage}, --map {' '.join(maps)}",
                          {"format": fmt, "maps": list(maps), "seed": int(rng.integers(2**31)),
                           "fraction": float(rng.random()), "bits": int(rng.integers(1, 17))}))
    return cases


def _storage(bag: Path) -> Path:
    if bag.is_file():
        return bag
    return next(p for p in sorted(bag.iterdir()) if p.name != "metadata.yaml")


def _damage(case: Case, bag: Path) -> str:
    rng = np.random.default_rng(case.data["seed"])
    damage = case.kind
    if damage == "none":
        return "intact"
    metadata = bag / "metadata.yaml" if bag.is_dir() else None
    if damage in ("no_metadata", "garbled_metadata", "metadata_counts") and metadata is None:
        damage = "flip"  # a ROS 1 bag has its index inside: damage that instead
    if damage == "no_metadata" and metadata is not None:
        metadata.unlink()
        return "metadata.yaml removed"
    if damage == "garbled_metadata" and metadata is not None:
        text = metadata.read_text(encoding="utf-8")
        cut = int(case.data["fraction"] * len(text))
        metadata.write_text(text[:cut] + "\n: [unclosed\n", encoding="utf-8")
        return f"metadata.yaml cut at {cut} and garbled"
    if damage == "metadata_counts" and metadata is not None:
        info = yaml.safe_load(metadata.read_text(encoding="utf-8"))
        body = info["rosbag2_bagfile_information"]
        body["message_count"] = int(rng.choice([0, -5, 10**12]))
        for topic in body.get("topics_with_message_count", []):
            topic["message_count"] = int(rng.choice([0, -1, 10**15]))
            if rng.random() < 0.5:
                topic["topic_metadata"]["type"] = "geometry_msgs/msg/Imu"
        metadata.write_text(yaml.safe_dump(info), encoding="utf-8")
        return "metadata.yaml counts and types changed"
    if damage == "no_storage":
        _storage(bag).unlink()
        return "storage file removed"
    target = _storage(bag)
    blob = bytearray(target.read_bytes())
    if damage == "truncate":
        cut = int(case.data["fraction"] * len(blob))
        target.write_bytes(bytes(blob[:cut]))
        return f"{target.name} cut at byte {cut} of {len(blob)}"
    if damage == "empty":
        target.write_bytes(b"")
        return f"{target.name} emptied"
    if damage == "junk":
        target.write_bytes(rng.integers(0, 256, len(blob), dtype=np.uint8).tobytes())
        return f"{target.name} replaced by {len(blob)} random bytes"
    offsets = rng.integers(0, len(blob), case.data["bits"])
    for offset in offsets:
        blob[int(offset)] ^= 1 << int(rng.integers(8))
    target.write_bytes(bytes(blob))
    return f"{len(offsets)} bit(s) flipped in {target.name}"


def check_bag_case(case: Case, workdir: Path, bags: dict[str, Path]) -> Outcome:
    """Damage a copy of the case's bag, import it, classify."""
    started = time.perf_counter()
    workdir.mkdir(parents=True, exist_ok=True)
    source = bags[case.data["format"]]
    bag = workdir / source.name
    if source.is_dir():
        shutil.copytree(source, bag)
    else:
        shutil.copyfile(source, bag)
    what = _damage(case, bag)
    before = snapshot(bag) if bag.is_dir() else {bag.name: snapshot(workdir).get(bag.name, "")}
    out = workdir / "imported"
    args = ["import-bag", str(bag), "--out", str(out)]
    for mapping in case.data["maps"]:
        args += ["--map", mapping]
    result = hapticframe_command(args, cwd=workdir)
    names = (bag.name, *(m.split("=")[0].split(":")[0] for m in case.data["maps"]),
             *case.data["maps"], "--map", "metadata.yaml")
    outcome = classify(case, result, started, names=names)
    outcome.detail = f"{what}; {outcome.detail}".strip("; ")
    after = snapshot(bag) if bag.is_dir() else {bag.name: snapshot(workdir).get(bag.name, "")}
    problems = compare_snapshots(before, after)
    if problems:
        return Outcome(case, "lost_or_mixed", False, f"{what}; the bag changed: "
                       f"{'; '.join(problems)}", outcome.seconds)
    if outcome.status == "ran":
        null = json_has_null_number(out / "import.json")
        if null is None and not (out / "run.mcap").is_file():
            null = "exit 0 without run.mcap"
        if null is None:
            text = (out / "import.json").read_text(encoding="utf-8")
            counts = [int(v) for v in _numbers_named(json.loads(text), "samples")]
            if counts and min(counts) <= 0:
                null = f"exit 0 with a sensor of {min(counts)} samples"
        if null:
            return Outcome(case, "null_result", False, f"{what}; {null}", outcome.seconds)
    return outcome


def _numbers_named(data: Any, word: str) -> list[float]:
    found: list[float] = []
    if isinstance(data, dict):
        for key, value in data.items():
            if word in str(key) and isinstance(value, int | float) and \
                    not isinstance(value, bool):
                found.append(value)
            else:
                found += _numbers_named(value, word)
    elif isinstance(data, list):
        for value in data:
            found += _numbers_named(value, word)
    return found
