"""Nothing lost, nothing mixed (issue 26 §1, §2): commands that would destroy a finished run
are refused, ``recover`` never writes in place, and one writer holds an output directory.

The concurrency cases are deterministic: the lock is taken in this process (an ``flock`` on
another open file conflicts with this process's own) or in a child process that has said it
holds it; no test relies on two commands racing.
"""

from __future__ import annotations

import json
import os
import shutil
import signal
import subprocess
import sys
from pathlib import Path

import pytest

from hapticframe._lock import LOCK_FILE, DirectoryBusy, lock_directory
from hapticframe.cli._cli import main
from hapticframe.record._recording import RECORDING, read_recording
from hapticframe.run._results import STAGING, OutputDir
from tests.core import test_recording_snapshots

from .test_overrides import TINY

#: A short search with a recording of many chunks (shared with the report's tests).
short_search = test_recording_snapshots.short_search

#: The tiny search, recorded.
RECORDED = TINY.replace("  record: false", "  record: true")


@pytest.fixture(scope="module")
def finished(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    """A finished, recorded run of the tiny search: (its experiment file, its directory)."""
    folder = tmp_path_factory.mktemp("guards")
    experiment = folder / "tiny.yaml"
    experiment.write_text(RECORDED, encoding="utf-8")
    out = folder / "run"
    assert main(["run", str(experiment), "--out", str(out), "--quiet"]) == 0
    return experiment, out


@pytest.fixture
def run_copy(finished: tuple[Path, Path], tmp_path: Path) -> Path:
    copy = tmp_path / "run"
    shutil.copytree(finished[1], copy)
    return copy


def _contents(folder: Path) -> dict[str, bytes]:
    return {p.relative_to(folder).as_posix(): p.read_bytes()
            for p in sorted(folder.rglob("*")) if p.is_file()}


# --- §1: commands that destroy a finished run ----------------------------------------------


def test_a_replay_into_its_own_input_is_refused(finished, run_copy, capsys):
    before = _contents(run_copy)
    assert main(["replay", str(run_copy), "--with", str(finished[0]), "--out", str(run_copy),
                 "--overwrite", "--quiet"]) == 2
    err = capsys.readouterr().err
    assert f"--out {run_copy} is also where this replay reads" in err
    assert "Traceback" not in err
    assert _contents(run_copy) == before


def test_overwrite_never_deletes_a_folder_a_tampered_record_lists(finished, run_copy, capsys):
    mine = run_copy / "mine"
    mine.mkdir()
    (mine / "thesis.tex").write_text("years of work")
    record = json.loads((run_copy / "run.json").read_text())
    record["files"].append("mine")
    (run_copy / "run.json").write_text(json.dumps(record))
    assert main(["run", str(finished[0]), "--out", str(run_copy), "--overwrite",
                 "--quiet"]) == 2
    err = capsys.readouterr().err
    assert "files hapticframe did not write (mine/" in err and "Traceback" not in err
    assert (mine / "thesis.tex").read_text() == "years of work"
    assert (run_copy / "trace.npz").is_file()  # nothing was cleared


def test_a_folder_hapticframe_made_is_cleared_by_name(tmp_path):
    """A folder a command moved in is listed with its files (``trees``); ``--overwrite``
    deletes those files and the folder, and refuses once something else is put in it."""
    def made(path: Path) -> OutputDir:
        directory = OutputDir.prepare(path, overwrite=True)
        directory.begin({"name": "x"})
        (directory.staging / "model" / "sub").mkdir(parents=True)
        (directory.staging / "model" / "sub" / "weights.npz").write_bytes(b"w")
        (directory.staging / "metrics.json").write_text("{}")
        record = {"status": "ok", "versions": {}}
        directory.finish(record, directory.commit(record))
        directory.release()
        return directory

    made(tmp_path / "a")
    record = json.loads((tmp_path / "a" / "run.json").read_text())
    assert record["trees"] == {"model": ["sub/weights.npz"]}
    made(tmp_path / "a")  # the earlier one cleared, folder and all
    assert sorted(os.listdir(tmp_path / "a")) == ["metrics.json", "model", "run.json"]
    (tmp_path / "a" / "model" / "notes.txt").write_text("mine")
    with pytest.raises(Exception, match=r"did not write \(model/"):
        OutputDir.prepare(tmp_path / "a", overwrite=True)
    assert (tmp_path / "a" / "model" / "notes.txt").read_text() == "mine"
    assert (tmp_path / "a" / "model" / "sub" / "weights.npz").is_file()


def _flip_a_bit_in_the_middle(path: Path) -> None:
    """Flip one bit inside the second of the recording's chunks (of several)."""
    from mcap.reader import make_reader

    with open(path, "rb") as stream:
        summary = make_reader(stream).get_summary()
    assert summary is not None
    chunks = sorted(summary.chunk_indexes, key=lambda c: c.chunk_start_offset)
    assert len(chunks) >= 3
    data = bytearray(path.read_bytes())
    data[chunks[1].chunk_start_offset + chunks[1].chunk_length // 2] ^= 0x10
    path.write_bytes(bytes(data))


@pytest.fixture
def search_copy(short_search: Path, tmp_path: Path) -> Path:
    copy = tmp_path / "search"
    shutil.copytree(short_search, copy)
    return copy


def test_recover_refuses_a_finished_run_unless_asked(search_copy, capsys):
    run_copy = search_copy
    _flip_a_bit_in_the_middle(run_copy / RECORDING)
    before = _contents(run_copy)
    assert main(["recover", str(run_copy)]) == 2
    err = capsys.readouterr().err
    assert "recording of a finished run" in err and "--finished" in err
    assert _contents(run_copy) == before


def test_recover_keeps_every_chunk_past_a_damaged_one_and_says_why(short_search,
                                                                   search_copy, capsys):
    run_copy = search_copy
    original = read_recording(short_search / RECORDING)
    total = sum(len(m) for m in original.values())
    _flip_a_bit_in_the_middle(run_copy / RECORDING)
    damaged = (run_copy / RECORDING).read_bytes()
    assert main(["recover", str(run_copy), "--finished"]) == 0
    printed = capsys.readouterr().out
    target = run_copy / "run.recovered.mcap"
    assert f"wrote {target}" in printed
    assert "skipped: the chunk at bytes" in printed
    assert "the bytes were changed after they were written" in printed  # a CRC or zstd check
    assert "ends inside a record" not in printed
    assert (run_copy / RECORDING).read_bytes() == damaged  # never replaced
    recovered = read_recording(target)
    kept = sum(len(m) for m in recovered.values())
    assert 0 < kept < total
    # Chunks after the damaged one are kept: the run's last messages are there.
    assert recovered["/metrics"] == original["/metrics"]
    assert recovered["/movement"][-1] == original["/movement"][-1]
    assert "run.recovered.mcap" in json.loads((run_copy / "run.json").read_text())["files"]
    # A second recover never replaces the first one's file.
    assert main(["recover", str(run_copy), "--finished"]) == 2
    assert "exists already" in capsys.readouterr().err


def test_a_killed_run_ends_recovered_with_the_next_step(finished, short_search, tmp_path,
                                                       capsys):
    """A run killed after its last sync: its staging folder holds the recording (cut) and
    its record says running. ``recover`` leaves a directory that says what it is."""
    killed = tmp_path / "killed"
    (killed / STAGING).mkdir(parents=True)
    data = (short_search / RECORDING).read_bytes()
    (killed / STAGING / RECORDING).write_bytes(data[:int(len(data) * 0.7)])
    (killed / STAGING / "forces.png").write_bytes(b"\x89PNG staged")
    record = json.loads((short_search / "run.json").read_text())
    running = {k: record[k] for k in ("experiment_file", "name", "seed", "started_utc")}
    (killed / "run.json").write_text(json.dumps({**running, "status": "running"}))
    assert main(["recover", str(killed)]) == 0
    printed = capsys.readouterr().out
    assert f"next: hapticframe report {killed}" in printed
    after = json.loads((killed / "run.json").read_text())
    assert after["status"] == "recovered" and after["recovered"]["messages"] > 0
    assert after["files"] == ["forces.png", "run.cut.mcap", RECORDING]
    assert not (killed / STAGING).exists() and not (killed / LOCK_FILE).exists()
    assert (killed / "run.cut.mcap").read_bytes() == data[:int(len(data) * 0.7)]
    # A recovered run is a finished one: a new run asks for --overwrite, which clears it.
    assert main(["run", str(finished[0]), "--out", str(killed), "--quiet"]) == 2
    assert "already holds a run" in capsys.readouterr().err
    assert main(["run", str(finished[0]), "--out", str(killed), "--quiet", "--overwrite"]) == 0
    assert not (killed / "run.cut.mcap").exists()
    # And the report of the recovered recording goes beside the run's results.
    assert main(["report", str(killed), "--no-figures"]) == 0


# --- §2: concurrent writers ------------------------------------------------------------------


@pytest.mark.parametrize("command", ["run", "train", "replay", "sweep"])
def test_a_second_writer_is_refused_at_once_naming_the_holder(finished, tmp_path, capsys,
                                                              command):
    experiment, run_dir = finished
    out = tmp_path / "busy"
    out.mkdir()
    argv = {
        "run": ["run", str(experiment), "--out", str(out), "--quiet"],
        "train": ["train", str(experiment), "--out", str(out)],
        "replay": ["replay", str(run_dir), "--with", str(experiment), "--out", str(out),
                   "--quiet"],
        "sweep": ["sweep", str(experiment), "--vary", "run.max_movements=1", "--trials", "1",
                  "--workers", "1", "--out", str(out)],
    }[command]
    with lock_directory(out, "run"):
        assert main(argv) == 2
        assert os.listdir(out) == [LOCK_FILE]  # nothing written, nothing cleared
    err = capsys.readouterr().err
    assert f"{out} is in use by run (pid {os.getpid()}, started " in err
    assert "Traceback" not in err
    assert not out.exists() or os.listdir(out) == []


#: A child process that takes the lock, says so, and holds it until its stdin closes.
_HOLDER = ("import sys; from hapticframe._lock import lock_directory; "
           "lock = lock_directory(sys.argv[1], 'run'); print('held', flush=True); "
           "sys.stdin.read()")


def test_the_lock_dies_with_its_process(tmp_path):
    """Held by a child process: refused with the child's pid; once the child is killed
    (SIGKILL, no clean-up), the directory is free."""
    child = subprocess.Popen([sys.executable, "-c", _HOLDER, str(tmp_path)],
                             stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
    try:
        assert child.stdout is not None and child.stdout.readline() == "held\n"
        with pytest.raises(DirectoryBusy) as caught:
            lock_directory(tmp_path, "report")
        assert caught.value.holder["pid"] == child.pid
        assert f"pid {child.pid}" in str(caught.value)
        os.kill(child.pid, signal.SIGKILL)
        child.wait(30)
        with lock_directory(tmp_path, "report") as lock:
            assert lock.held
    finally:
        child.kill()
        child.wait(30)


def test_a_sweep_never_mixes_into_a_run_or_a_users_files(finished, run_copy, tmp_path,
                                                         capsys):
    experiment = finished[0]
    sweep = ["sweep", str(experiment), "--vary", "run.max_movements=1", "--trials", "1",
             "--workers", "1"]
    before = _contents(run_copy)
    assert main([*sweep, "--out", str(run_copy)]) == 2
    assert "holds files but no sweep.json" in capsys.readouterr().err
    assert _contents(run_copy) == before
    own = tmp_path / "own"
    own.mkdir()
    (own / "sweep.md").write_text("my notes")
    assert main([*sweep, "--out", str(own), "--overwrite"]) == 2
    capsys.readouterr()
    assert (own / "sweep.md").read_text() == "my notes"


def test_a_sweep_again_needs_overwrite_and_leaves_no_stale_points(finished, tmp_path, capsys):
    experiment = finished[0]
    out = tmp_path / "sweep"
    two = ["sweep", str(experiment), "--vary", "run.max_movements=1", "--trials", "1",
           "--workers", "1", "--out", str(out)]
    assert main(two) == 0
    assert sorted(os.listdir(out / "points")) == ["p000", "p001"]
    assert main(two) == 2
    assert "already holds a sweep" in capsys.readouterr().err
    one = ["sweep", str(experiment), "--vary", "run.max_movements=2", "--trials", "1",
           "--workers", "1", "--out", str(out), "--overwrite"]
    assert main(one) == 0  # 2 is the file's value: the baseline alone
    result = json.loads((out / "sweep.json").read_text())
    assert result["status"] == "ok" and len(result["points"]) == 1
    assert sorted(os.listdir(out / "points")) == ["p000"]
    assert all(Path(row["run_dir"]).is_dir() for row in result["runs"])
