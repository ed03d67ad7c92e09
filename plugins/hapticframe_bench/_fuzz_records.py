"""The ``recordings`` family of ``hapticframe bench fuzz``: damaged ``run.mcap`` files.

A finished run's recording is damaged one way — cut at a random byte, bits flipped inside a
chunk's records, a chunk's, the data section's or the summary's CRC flipped, bytes flipped
anywhere, replaced by another experiment's recording or by bytes that are no recording —
and read by one command: ``recover --finished``, ``report`` (into a folder of its own, or
into the run's directory beside its files),
``replay`` (into a new folder) or a run whose sensor is the ``recording`` sensor reading it.
The run's own files must stay as they were (``run.json`` may only list more files), and a
command that ends with exit 0 must leave strict, non-null results.
"""

from __future__ import annotations

import json
import shutil
import struct
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

__all__ = ["COMMANDS", "DAMAGES", "RecordFixtures", "check_record_case", "generate_record_cases",
           "make_record_fixtures", "mcap_layout"]

DAMAGES = ("truncate", "flip_chunk", "flip_chunk_crc", "flip_data_crc", "flip_summary_crc",
           "flip_any", "foreign", "junk")
COMMANDS = ("recover", "report", "report_beside", "replay", "sensor")
_MAGIC = b"\x89MCAP0\r\n"
_CHUNK, _DATA_END, _FOOTER = 0x06, 0x0F, 0x02


class RecordFixtures:
    """Two finished runs made once per bench: ``base`` (the search example) and ``foreign``
    (another experiment), each one movement long."""

    def __init__(self, root: Path, examples: Path) -> None:
        self.root = root
        self.examples = examples
        self.base = root / "base"
        self.foreign = root / "foreign"
        self.experiment = root / "base.yaml"

    def ready(self) -> bool:
        return (self.base / "run.mcap").exists() and (self.foreign / "run.mcap").exists()


def make_record_fixtures(root: Path, examples: Path) -> RecordFixtures:
    """Run the two fixture runs (about a second each) into ``root``."""
    fixtures = RecordFixtures(root, examples)
    root.mkdir(parents=True, exist_ok=True)
    data = yaml.safe_load((examples / "search-ellipse.yaml").read_text(encoding="utf-8"))
    data.setdefault("run", {}).update({"max_movements": 1, "figures": False})
    fixtures.experiment.write_text(yaml.safe_dump(data), encoding="utf-8")
    foreign = yaml.safe_load((examples / "search-two-arms.yaml").read_text(encoding="utf-8"))
    foreign.setdefault("run", {}).update({"max_movements": 1, "figures": False})
    (root / "foreign.yaml").write_text(yaml.safe_dump(foreign), encoding="utf-8")
    for experiment, out in ((fixtures.experiment, fixtures.base),
                            (root / "foreign.yaml", fixtures.foreign)):
        done = hapticframe_command(["run", str(experiment), "--out", str(out), "--quiet"])
        if done.returncode != 0:
            raise RuntimeError(f"the fixture run {out.name} failed: {done.last_line}")
    return fixtures


def mcap_layout(blob: bytes) -> dict[str, list[tuple[int, int]]]:
    """Where the records of an MCAP file lie: ``chunk`` (the records inside each chunk,
    start and end), ``chunk_crc`` (each chunk's CRC field), ``data_crc`` and
    ``summary_crc`` (their 4-byte fields). Stops quietly at anything it cannot parse."""
    layout: dict[str, list[tuple[int, int]]] = {
        "chunk": [], "chunk_crc": [], "data_crc": [], "summary_crc": []}
    at = len(_MAGIC)
    while at + 9 <= len(blob):
        opcode = blob[at]
        (length,) = struct.unpack_from("<Q", blob, at + 1)
        body = at + 9
        if length > len(blob) - body:
            break
        if opcode == _CHUNK and length >= 36:
            layout["chunk_crc"].append((body + 24, body + 28))
            (name_len,) = struct.unpack_from("<I", blob, body + 28)
            records = body + 32 + name_len + 8
            if records <= body + length:
                layout["chunk"].append((records, body + length))
        elif opcode == _DATA_END and length >= 4:
            layout["data_crc"].append((body, body + 4))
        elif opcode == _FOOTER and length >= 20:
            layout["summary_crc"].append((body + 16, body + 20))
        at = body + length
    return layout


def _flip(blob: bytearray, spans: list[tuple[int, int]], rng: np.random.Generator,
          bits: int) -> str:
    spans = [s for s in spans if s[1] > s[0]]
    if not spans:
        return "nothing to flip"
    where = []
    for _ in range(bits):
        start, end = spans[int(rng.integers(len(spans)))]
        offset = int(rng.integers(start, end))
        blob[offset] ^= 1 << int(rng.integers(8))
        where.append(offset)
    return f"{bits} bit(s) at byte {', '.join(map(str, sorted(where)[:4]))}"


def _junk(rng: np.random.Generator) -> bytes:
    kind = int(rng.integers(5))
    if kind == 0:
        return b""
    if kind == 1:
        return _MAGIC
    if kind == 2:
        return b"not a recording\n" * int(rng.integers(1, 100))
    if kind == 3:
        return bytes(int(rng.integers(1, 5000)))
    return rng.integers(0, 256, int(rng.integers(1, 20000)), dtype=np.uint8).tobytes()


def generate_record_cases(count: int, seed: int) -> list[Case]:
    """``count`` cases: each damage in turn, the command drawn (seeded)."""
    rng = np.random.default_rng(seed)
    cases = []
    for k in range(count):
        damage = DAMAGES[k % len(DAMAGES)]
        command = COMMANDS[int(rng.integers(len(COMMANDS)))]
        cases.append(Case("recordings", damage, f"{damage} → {command}",
                          {"command": command, "seed": int(rng.integers(2**31)),
                           "fraction": float(rng.random()), "bits": int(rng.integers(1, 9))}))
    return cases


def _damage(case: Case, run_dir: Path, fixtures: RecordFixtures) -> str:
    path = run_dir / "run.mcap"
    rng = np.random.default_rng(case.data["seed"])
    blob = bytearray(path.read_bytes())
    layout = mcap_layout(bytes(blob))
    bits = case.data["bits"]
    if case.kind == "truncate":
        cut = int(case.data["fraction"] * len(blob))
        path.write_bytes(bytes(blob[:cut]))
        return f"cut at byte {cut} of {len(blob)}"
    if case.kind == "foreign":
        shutil.copyfile(fixtures.foreign / "run.mcap", path)
        return "another experiment's run.mcap"
    if case.kind == "junk":
        junk = _junk(rng)
        path.write_bytes(junk)
        return f"{len(junk)} bytes that are no recording"
    spans = {"flip_chunk": layout["chunk"], "flip_chunk_crc": layout["chunk_crc"],
             "flip_data_crc": layout["data_crc"], "flip_summary_crc": layout["summary_crc"],
             "flip_any": [(len(_MAGIC), len(blob))]}[case.kind]
    what = _flip(blob, spans, rng, 1 if "crc" in case.kind else bits)
    path.write_bytes(bytes(blob))
    return what


def _sensor_experiment(fixtures: RecordFixtures, recording: Path, target: Path) -> None:
    data = yaml.safe_load(fixtures.experiment.read_text(encoding="utf-8"))
    for sensor in data["sensors"]:
        if sensor["id"] == "wrist":
            sensor.update({"type": "recording", "inputs": [],
                           "config": {"file": str(recording), "topic": "/sensor/wrist"}})
    target.write_text(yaml.safe_dump(data), encoding="utf-8")


def _run_json_listing_only(before: Path, after_text: str) -> str | None:
    """None when ``run.json`` changed only by listing more files."""
    try:
        old = json.loads(before.read_text(encoding="utf-8"))
        new = json.loads(after_text)
    except ValueError as exc:
        return f"run.json no longer JSON ({exc})"
    old_files, new_files = old.pop("files", []), new.pop("files", [])
    if old != new:
        changed = sorted(k for k in set(old) | set(new) if old.get(k) != new.get(k))
        return f"run.json rewritten ({', '.join(changed)})"
    if not set(old_files) <= set(new_files):
        return "run.json lists fewer files"
    return None


def check_record_case(case: Case, workdir: Path, fixtures: RecordFixtures) -> Outcome:
    """Damage a copy of the base run, run the case's command on it, and classify."""
    started = time.perf_counter()
    workdir.mkdir(parents=True, exist_ok=True)
    run_dir = workdir / "run"
    shutil.copytree(fixtures.base, run_dir)
    what = _damage(case, run_dir, fixtures)
    saved_run_json = workdir / "run.json.before"
    shutil.copyfile(run_dir / "run.json", saved_run_json)
    before = snapshot(run_dir)
    command = case.data["command"]
    out = workdir / "out"
    args: list[str]
    if command == "recover":
        args = ["recover", str(run_dir), "--finished"]
    elif command == "report":
        args = ["report", str(run_dir), "--out", str(out), "--no-figures"]
    elif command == "report_beside":  # into the run's own directory, beside its files
        args = ["report", str(run_dir), "--no-figures"]
    elif command == "replay":
        args = ["replay", str(run_dir), "--with", str(fixtures.experiment), "--out", str(out),
                "--quiet"]
    else:
        experiment = workdir / "sensor.yaml"
        _sensor_experiment(fixtures, run_dir / "run.mcap", experiment)
        args = ["run", str(experiment), "--out", str(out), "--quiet"]
    result = hapticframe_command(args, cwd=workdir)
    outcome = classify(case, result, started, names=("run.mcap", str(run_dir), "recording"))
    outcome.detail = f"{what}; {outcome.detail}".strip("; ")
    after = snapshot(run_dir)
    problems = compare_snapshots(before, after, may_change=("run.json",))
    if before.get("run.json") != after.get("run.json"):
        text = (run_dir / "run.json").read_text(encoding="utf-8") \
            if (run_dir / "run.json").exists() else "{}"
        problem = _run_json_listing_only(saved_run_json, text)
        if problem:
            problems.append(problem)
    if problems:
        return Outcome(case, "lost_or_mixed", False, f"{what}; {'; '.join(problems)}",
                       outcome.seconds)
    if outcome.status == "ran" and command in ("replay", "sensor"):
        null = json_has_null_number(out / "metrics.json")
        if null is None:
            metrics = json.loads((out / "metrics.json").read_text(encoding="utf-8"))
            if not isinstance(metrics.get("movements"), int):
                null = "metrics.json has no movement count"
        if null:
            return Outcome(case, "null_result", False, f"{what}; {null}", outcome.seconds)
    report_dir = run_dir if command == "report_beside" else out
    if outcome.status == "ran" and command.startswith("report") and \
            not any(report_dir.glob("report_*")):
        return Outcome(case, "null_result", False, f"{what}; exit 0 and no report written",
                       outcome.seconds)
    return outcome


def describe_fixture_versions(fixtures: RecordFixtures) -> dict[str, Any]:
    """The fixture runs' sizes (for the report)."""
    return {name: (d / "run.mcap").stat().st_size for name, d in
            (("base", fixtures.base), ("foreign", fixtures.foreign))}
