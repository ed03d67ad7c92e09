"""The ``writers`` family of ``hapticframe bench fuzz``: two writers, one output directory.

* ``locked``: a child process holds the directory's lock first (deterministic: it holds it
  before the second command starts), and a second ``run`` (with or without
  ``--overwrite``), ``sweep``, ``replay`` (with or without ``--overwrite``), ``report`` or
  ``recover`` is started into it; the directory is empty or holds a finished run. The
  second writer must be refused at once (exit 2, naming the directory) and leave every
  file as it was.
* ``race``: two ``run``s of different seeds started together into one empty directory (the
  second one with ``--overwrite`` in half the cases). The directory must end holding one
  run: its ``run.json`` names the seed of a writer that succeeded, lists every file there,
  and every file it lists exists.
* ``tampered``: a finished run's ``run.json`` lists files the project did not write (a user's
  file, a user's folder, a path outside, the directory itself); ``run --overwrite`` into it
  must leave every one of them.
"""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

from hapticframe_bench._fuzz_common import (
    Case,
    Outcome,
    classify,
    compare_snapshots,
    hapticframe_command,
    snapshot,
)
from hapticframe_bench._fuzz_records import RecordFixtures

__all__ = ["SECOND_WRITERS", "TAMPERED", "check_writer_case", "generate_writer_cases"]

SECOND_WRITERS = ("run", "run_overwrite", "sweep", "replay", "replay_overwrite", "report",
                  "recover")
#: What a tampered run.json lists (``{outside}`` is a file beside the directory).
TAMPERED = ("notes.txt", "userdir", "userdir/data.csv", "{outside}", "{outside_abs}", ".",
            "", "..", "userdir/../notes.txt", "/", "run.mcap/../notes.txt")
_HOLDER = ("import sys, hapticframe\n"
           "lock = hapticframe.lock_directory(sys.argv[1], 'fuzz-holder')\n"
           "print('held', flush=True)\n"
           "sys.stdin.read()\n"
           "lock.release()\n")


def generate_writer_cases(count: int, seed: int) -> list[Case]:
    """``count`` cases: ``locked`` 6 in 10, ``tampered`` 3 in 10, ``race`` 1 in 10."""
    rng = np.random.default_rng(seed)
    cases = []
    for k in range(count):
        slot = k % 10
        if slot < 6:
            second = SECOND_WRITERS[int(rng.integers(len(SECOND_WRITERS)))]
            state = ("empty", "finished")[int(rng.integers(2))]
            cases.append(Case("writers", "locked", f"{second} into a locked {state} directory",
                              {"second": second, "state": state}))
        elif slot < 9:
            picks = sorted({int(i) for i in rng.integers(len(TAMPERED), size=3)})
            listed = [TAMPERED[i] for i in picks]
            cases.append(Case("writers", "tampered",
                              f"run --overwrite over run.json listing {listed}",
                              {"listed": listed}))
        else:
            overwrite = bool(rng.integers(2))
            cases.append(Case("writers", "race", "two runs at once"
                              + (" (the second --overwrite)" if overwrite else ""),
                              {"overwrite": overwrite, "seed": int(rng.integers(1, 1000))}))
    return cases


def _second_args(second: str, target: Path, fixtures: RecordFixtures) -> list[str]:
    experiment = str(fixtures.experiment)
    if second.startswith("run"):
        return ["run", experiment, "--out", str(target), "--quiet"] + (
            ["--overwrite"] if second.endswith("overwrite") else [])
    if second == "sweep":
        return ["sweep", experiment, "--vary", "seed=1,2", "--trials", "1", "--workers", "1",
                "--out", str(target)]
    if second.startswith("replay"):
        return ["replay", str(fixtures.base), "--with", experiment, "--out", str(target),
                "--quiet"] + (["--overwrite"] if second.endswith("overwrite") else [])
    if second == "report":
        return ["report", str(target), "--no-figures"]
    return ["recover", str(target), "--finished"]


def _locked(case: Case, workdir: Path, fixtures: RecordFixtures, started: float) -> Outcome:
    target = workdir / "out"
    if case.data["state"] == "finished":
        shutil.copytree(fixtures.base, target)
    else:
        target.mkdir(parents=True)
    before = snapshot(target)
    holder = subprocess.Popen([sys.executable, "-c", _HOLDER, str(target)],
                              stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
    try:
        assert holder.stdout is not None
        if holder.stdout.readline().strip() != "held":
            return Outcome(case, "unexpected", False, "the lock holder did not take the lock",
                           time.perf_counter() - started)
        result = hapticframe_command(_second_args(case.data["second"], target, fixtures),
                                     cwd=workdir)
    finally:
        if holder.stdin is not None:
            holder.stdin.close()
        holder.wait(30)
    outcome = classify(case, result, started, names=(str(target),))
    problems = compare_snapshots(before, snapshot(target))
    new = sorted(set(snapshot(target)) - set(before))
    if problems or new:
        return Outcome(case, "lost_or_mixed", False,
                       "; ".join(problems + [f"{n} written beside the holder" for n in new]),
                       outcome.seconds)
    if outcome.ok and outcome.status != "refused":
        return Outcome(case, "lost_or_mixed", False,
                       f"a second writer was not refused ({outcome.status})", outcome.seconds)
    return outcome


def _tampered(case: Case, workdir: Path, fixtures: RecordFixtures, started: float) -> Outcome:
    target = workdir / "out"
    shutil.copytree(fixtures.base, target)
    (target / "notes.txt").write_text("a user's notes\n", encoding="utf-8")
    (target / "userdir").mkdir()
    (target / "userdir" / "data.csv").write_text("a,b\n1,2\n", encoding="utf-8")
    outside = workdir / "outside.txt"
    outside.write_text("a user's file beside the run\n", encoding="utf-8")
    listed = [name.format(outside="../outside.txt", outside_abs=str(outside))
              for name in case.data["listed"]]
    record_path = target / "run.json"
    record = json.loads(record_path.read_text(encoding="utf-8"))
    record["files"] = list(record.get("files", [])) + listed
    record_path.write_text(json.dumps(record), encoding="utf-8")
    users = {"notes.txt": target / "notes.txt", "userdir/data.csv":
             target / "userdir" / "data.csv", "../outside.txt": outside}
    kept = {name: path.read_bytes() for name, path in users.items()}
    result = hapticframe_command(["run", str(fixtures.experiment), "--out", str(target),
                                  "--overwrite", "--quiet"], cwd=workdir)
    outcome = classify(case, result, started, names=(str(target), "run.json"))
    lost = [name for name, path in users.items()
            if not path.exists() or path.read_bytes() != kept[name]]
    if lost:
        return Outcome(case, "lost_or_mixed", False,
                       f"user files deleted or changed: {', '.join(lost)}", outcome.seconds)
    return outcome


def _race(case: Case, workdir: Path, fixtures: RecordFixtures, started: float) -> Outcome:
    target = workdir / "out"
    seeds = (case.data["seed"], case.data["seed"] + 1)
    commands = []
    for i, seed in enumerate(seeds):
        args = ["run", str(fixtures.experiment), "--out", str(target), "--quiet",
                "--set", f"seed={seed}"]
        if i == 1 and case.data["overwrite"]:
            args.append("--overwrite")
        commands.append([sys.executable, "-m", "hapticframe", *args])
    children = [subprocess.Popen(c, cwd=workdir, stdout=subprocess.PIPE,
                                 stderr=subprocess.PIPE, text=True) for c in commands]
    ends = [child.communicate(timeout=300) for child in children]
    seconds = time.perf_counter() - started
    codes = [child.returncode for child in children]
    for (_, stderr), code in zip(ends, codes, strict=True):
        if "internal error" in stderr or "Traceback" in stderr:
            return Outcome(case, "internal_error", False, stderr.strip().splitlines()[-1][:300],
                           seconds)
        if code not in (0, 2):
            return Outcome(case, "unexpected", False, f"exit {code}", seconds)
    winners = [seed for seed, code in zip(seeds, codes, strict=True) if code == 0]
    if not winners:
        return Outcome(case, "lost_or_mixed", False, "neither run finished", seconds)
    record = json.loads((target / "run.json").read_text(encoding="utf-8"))
    files = set(snapshot(target)) - {"run.json"}
    listed = set(record.get("files", []))
    problems = []
    if record.get("seed") not in winners:
        problems.append(f"run.json names seed {record.get('seed')}, the runs that ended "
                        f"were {winners}")
    if record.get("status") != "ok":
        problems.append(f"run.json status {record.get('status')!r}")
    if files - listed:
        problems.append(f"unlisted files {sorted(files - listed)}")
    if listed - files:
        problems.append(f"listed files missing {sorted(listed - files)}")
    if problems:
        return Outcome(case, "lost_or_mixed", False, "; ".join(problems), seconds)
    refused = [code for code in codes if code == 2]
    return Outcome(case, "refused" if refused else "ran", True,
                   f"exits {codes}", seconds)


def check_writer_case(case: Case, workdir: Path, fixtures: RecordFixtures) -> Outcome:
    """Set the directory up, start the writers, classify."""
    started = time.perf_counter()
    workdir.mkdir(parents=True, exist_ok=True)
    if case.kind == "locked":
        return _locked(case, workdir, fixtures, started)
    if case.kind == "tampered":
        return _tampered(case, workdir, fixtures, started)
    return _race(case, workdir, fixtures, started)
