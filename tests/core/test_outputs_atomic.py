"""Outputs are atomic and a run's directory tells the truth (issue 16, section 3).

Each reproduction of the issue is a test here: ``kill -9`` at points of ``run`` and
``train`` (a forked child kills itself), a full disk (``os.write`` raising ENOSPC), a disk
short of space (a fake ``shutil.disk_usage``), a read-only ``--out``, ``--out`` below a
file, and stale or foreign files with ``--overwrite``.
"""

from __future__ import annotations

import errno
import json
import os
import shutil
import signal
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest

import hapticframe.run._assembly as assembly
import hapticframe.run._results as results
import hapticframe.run._train  # noqa: F401  (binds the real build_components before tests patch it)
from hapticframe._lock import LOCK_FILE
from hapticframe.plotting import new_figure, save_figure
from hapticframe.run._results import (
    STAGING,
    TEMP_PREFIX,
    OutputError,
    atomic_write,
    save_npz,
    write_json,
)
from tests.support.lab import lab_main

needs_fork = pytest.mark.skipif(not hasattr(os, "fork"), reason="needs os.fork")


@pytest.fixture
def experiment(lab_dir: Path) -> Path:
    """The lab's open-loop experiment without figures (fast)."""
    path = lab_dir / "lab-open-loop.yaml"
    path.write_text(path.read_text() + "run: {figures: false}\n")
    return path


def run(experiment: Path, out: Path, *extra: str) -> int:
    return lab_main(["run", str(experiment), "--out", str(out), "--quiet", *extra])


def record(out: Path, name: str = "run.json") -> dict[str, Any]:
    data: dict[str, Any] = json.loads((out / name).read_text())
    return data


def assert_finished(out: Path, status: str = "ok", name: str = "run.json") -> dict[str, Any]:
    """A finished directory: the record has the status and lists exactly the other files."""
    data = record(out, name)
    assert data["status"] == status
    present = sorted(n for n in os.listdir(out) if n != name)
    assert present == data["files"]
    return data


def killed_at(patch: Callable[[], None], argv: list[str]) -> None:
    """Run ``hapticframe argv`` in a forked child that ``patch`` makes SIGKILL itself."""
    pid = os.fork()
    if pid == 0:  # pragma: no cover - the child never returns
        try:
            patch()
            code = lab_main(argv)
            os.write(2, f"the patch did not fire; exit status {code}\n".encode())
        finally:
            os._exit(3)
    _, status = os.waitpid(pid, 0)
    assert os.WIFSIGNALED(status) and os.WTERMSIG(status) == signal.SIGKILL


def kill_self(*_args: Any, **_kwargs: Any) -> None:
    sys.stdout.flush()
    os.kill(os.getpid(), signal.SIGKILL)


# --- the helpers -----------------------------------------------------------------------------


def _failing_write(after: int) -> Callable[[int, Any], int]:
    """An ``os.write`` that writes ``after`` bytes and then finds the disk full."""
    real = os.write
    budget = [after]

    def write(fd: int, data: Any) -> int:
        if budget[0] <= 0:
            raise OSError(errno.ENOSPC, "No space left on device")
        chunk = bytes(data)[: budget[0]]
        budget[0] -= len(chunk)
        return real(fd, chunk)

    return write


def test_a_write_cut_by_a_full_disk_leaves_the_previous_file_and_no_temporary(
        tmp_path, monkeypatch):
    path = tmp_path / "run.json"
    write_json(path, {"status": "ok", "values": list(range(10))})
    before = path.read_bytes()
    monkeypatch.setattr(os, "write", _failing_write(after=16))
    with pytest.raises(OutputError, match=r"cannot write .*run\.json: No space left on device "
                                          r"\(ENOSPC\); free some space") as info:
        write_json(path, {"status": "running", "values": list(range(5000))})
    assert info.value.path == path and info.value.exit_code == 1
    assert path.read_bytes() == before
    assert os.listdir(tmp_path) == ["run.json"]


def test_atomic_helpers_write_complete_files(tmp_path):
    atomic_write(tmp_path / "a.txt", "héllo")
    assert (tmp_path / "a.txt").read_text(encoding="utf-8") == "héllo"
    save_npz(tmp_path / "t.npz", x=np.arange(3.0))
    with np.load(tmp_path / "t.npz") as data:
        assert np.array_equal(data["x"], [0.0, 1.0, 2.0])
    with pytest.raises(ValueError, match="npz"):
        save_npz(tmp_path / "t.npy", x=np.arange(3.0))
    assert sorted(os.listdir(tmp_path)) == ["a.txt", "t.npz"]


def test_a_figure_save_that_fails_midway_spoils_nothing(tmp_path, monkeypatch):
    figure = new_figure(2, 2)
    path = save_figure(figure, tmp_path / "outline.png")
    before = path.read_bytes()
    assert before.startswith(b"\x89PNG")

    def half_then_full(self: Any, target: Any, **kwargs: Any) -> None:
        Path(target).write_bytes(b"\x89PNG partial")
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(type(figure), "savefig", half_then_full)
    with pytest.raises(OutputError, match=r"outline\.png: No space left"):
        save_figure(figure, path)
    assert path.read_bytes() == before and os.listdir(tmp_path) == ["outline.png"]


# --- run: what is written, and when ----------------------------------------------------------


def test_run_json_says_running_before_anything_is_built(experiment, monkeypatch):
    out = experiment.parent / "run"
    seen: list[dict[str, Any]] = []
    build = assembly.build_components

    def spy(*args: Any, **kwargs: Any) -> Any:
        seen.append(record(out))
        assert os.path.isdir(out / STAGING)
        return build(*args, **kwargs)

    monkeypatch.setattr(assembly, "build_components", spy)
    assert run(experiment, out) == 0
    assert seen[0]["status"] == "running" and seen[0]["pid"] == os.getpid()
    data = assert_finished(out)
    assert data["files"] == ["metrics.json", "run.mcap", "trace.npz"]
    assert not (out / STAGING).exists()


@needs_fork
@pytest.mark.parametrize("point", ["build", "trace", "commit", "move"])
def test_kill_9_leaves_an_unfinished_run_that_is_refused_then_cleared(experiment, point, capsys):
    out = experiment.parent / "run"
    argv = ["run", str(experiment), "--out", str(out), "--quiet"]

    def patch() -> None:
        if point == "build":
            assembly.build_components = kill_self  # type: ignore[assignment]
        elif point == "trace":  # the trace half written
            from hapticframe.run._streams import TraceRecorder

            def half(self: Any, path: str) -> None:
                Path(path).write_bytes(b"PK\x03\x04 truncated")
                kill_self()

            TraceRecorder.save = half  # type: ignore[method-assign]
        elif point == "commit":  # every file written, run.json not yet updated
            results.OutputDir.commit = kill_self  # type: ignore[method-assign,assignment]
        else:  # between moving one file into place and the next
            real, moved = os.replace, [0]

            def replace(source: Any, target: Any) -> None:
                if STAGING in str(source) and not Path(source).name.startswith(TEMP_PREFIX):
                    if moved[0]:
                        kill_self()
                    moved[0] += 1
                real(source, target)

            os.replace = replace  # type: ignore[assignment]

    killed_at(patch, argv)
    data = record(out)
    assert data["status"] == "running"  # never a directory that looks finished
    for name in os.listdir(out):  # no empty or cut file where results belong
        # The lock file of the killed process stays: no lock any more (the kernel let it go).
        assert name in ("run.json", STAGING, LOCK_FILE) or name in data.get("files", ())
        if (out / name).is_file():
            assert (out / name).stat().st_size > 0
    if point == "move":
        assert data["files"] == ["metrics.json", "run.mcap", "trace.npz"]
    capsys.readouterr()
    assert run(experiment, out) == 2
    err = capsys.readouterr().err
    assert "holds an unfinished run" in err and "--overwrite" in err and "Traceback" not in err
    assert run(experiment, out, "--overwrite") == 0
    assert_finished(out)


def test_results_without_run_json_are_refused_even_with_overwrite(experiment, capsys):
    out = experiment.parent / "run"
    out.mkdir()
    (out / "metrics.json").write_text("{}")
    (out / "trace.npz").write_bytes(b"")
    for extra in ((), ("--overwrite",)):
        assert run(experiment, out, *extra) == 2
        err = capsys.readouterr().err
        assert "holds files but no run.json (metrics.json, trace.npz)" in err
        assert "empty it yourself" in err
    assert sorted(os.listdir(out)) == ["metrics.json", "trace.npz"]


def test_a_corrupt_run_json_is_refused_with_what_to_do(experiment, capsys):
    out = experiment.parent / "run"
    out.mkdir()
    (out / "run.json").write_text('{"status": "ok", "err')  # cut at a block boundary
    assert run(experiment, out, "--overwrite") == 2
    err = capsys.readouterr().err
    assert "run.json is not a hapticframe record" in err and "internal error" not in err


def test_overwrite_deletes_the_previous_runs_files_and_only_those(experiment, capsys):
    out = experiment.parent / "run"
    assert run(experiment, out) == 0
    # A previous run that wrote more (a killed baseline's logodds_phase*.png):
    stale = record(out)
    (out / "logodds_phase3.png").write_bytes(b"old")
    stale["files"].append("logodds_phase3.png")
    stale["files"].append("../lab-open-loop.yaml")  # a listed name is never followed out
    (out / "run.json").write_text(json.dumps(stale))
    (out / ".keep").write_text("")  # hidden files are no results: kept
    assert run(experiment, out, "--overwrite") == 0
    assert not (out / "logodds_phase3.png").exists() and (out / ".keep").exists()
    assert experiment.exists()
    assert record(out)["files"] == ["metrics.json", "run.mcap", "trace.npz"]

    (out / "notes.txt").write_text("mine")
    metrics = (out / "metrics.json").read_bytes()
    capsys.readouterr()
    assert run(experiment, out, "--overwrite") == 2
    err = capsys.readouterr().err
    assert "would have to delete files hapticframe did not write (notes.txt" in err
    assert (out / "metrics.json").read_bytes() == metrics and (out / "notes.txt").exists()


def test_a_failure_to_build_leaves_nothing(experiment, monkeypatch, capsys):
    out = experiment.parent / "new" / "run"

    def fail(*_args: Any, **_kwargs: Any) -> None:
        from hapticframe import RunError

        raise RunError("cannot build 'sweep': the port is busy")

    monkeypatch.setattr(assembly, "build_components", fail)
    assert run(experiment, out) == 1
    assert not (experiment.parent / "new").exists()


# --- the --out directory, checked before anything runs ---------------------------------------


def _must_not_build(monkeypatch: pytest.MonkeyPatch) -> None:
    def fail(*_args: Any, **_kwargs: Any) -> None:
        raise AssertionError("built although --out is unusable")

    monkeypatch.setattr(assembly, "build_components", fail)


def test_out_below_a_regular_file_is_a_located_usage_error(experiment, monkeypatch, capsys):
    _must_not_build(monkeypatch)
    (experiment.parent / "afile").write_text("x")
    assert run(experiment, experiment.parent / "afile" / "run") == 2
    err = capsys.readouterr().err
    assert f"{experiment.parent / 'afile'} is not a directory" in err
    assert "internal error" not in err
    assert run(experiment, experiment.parent / "afile") == 2


def _ten_megabytes_free(_path: Any) -> Any:
    return shutil._ntuple_diskusage(100 * 2**20, 90 * 2**20, 10 * 2**20)


def test_too_little_free_space_fails_before_the_run(experiment, monkeypatch, capsys):
    _must_not_build(monkeypatch)
    monkeypatch.setattr(results.shutil, "disk_usage", _ten_megabytes_free)
    out = experiment.parent / "run"
    assert run(experiment, out) == 1
    err = capsys.readouterr().err
    assert "has 10.0 MB free; a run needs at least 50.0 MB" in err
    assert not out.exists()
    monkeypatch.setenv("HAPTICFRAME_MIN_FREE_MB", "nonsense")
    assert run(experiment, out) == 2
    monkeypatch.undo()
    monkeypatch.setattr(results.shutil, "disk_usage", _ten_megabytes_free)
    assert run(experiment, out, "--min-free-mb", "5") == 0


def test_an_unwritable_out_fails_before_the_run(experiment, monkeypatch, capsys):
    _must_not_build(monkeypatch)
    out = experiment.parent / "run"
    out.mkdir()
    real = os.open

    def read_only(path: Any, flags: int, *args: Any) -> int:
        if str(path).startswith(str(out)) and flags & os.O_WRONLY:
            raise OSError(errno.EROFS, "Read-only file system")
        return real(path, flags, *args)

    monkeypatch.setattr(os, "open", read_only)
    assert run(experiment, out) == 1
    err = capsys.readouterr().err
    assert f"--out {out} is not writable" in err and "Read-only file system" in err
    assert os.listdir(out) == []


@pytest.mark.skipif(not hasattr(os, "geteuid") or os.geteuid() == 0,
                    reason="root ignores file modes")
def test_a_read_only_out_directory_fails_before_the_run(experiment, monkeypatch, capsys):
    _must_not_build(monkeypatch)
    out = experiment.parent / "run"
    out.mkdir()
    out.chmod(0o555)
    try:
        assert run(experiment, out) == 1
        assert "is not writable" in capsys.readouterr().err
    finally:
        out.chmod(0o755)


# --- errors while running --------------------------------------------------------------------


def _full_disk_for(monkeypatch: pytest.MonkeyPatch, out: Path, names: tuple[str, ...]) -> None:
    """``os.write`` raises ENOSPC for files under ``out`` whose name ends with one of
    ``names`` (a temporary's name ends with its target's), from the first write of
    ``names[0]`` on: the disk fills up while the run runs."""
    real = os.write
    full = [False]

    def write(fd: int, data: Any) -> int:
        target = os.readlink(f"/proc/self/fd/{fd}")
        full[0] = full[0] or target.endswith(names[0])
        if full[0] and target.startswith(str(out)) and target.endswith(names):
            raise OSError(errno.ENOSPC, "No space left on device")
        return real(fd, data)

    monkeypatch.setattr(os, "write", write)


needs_proc = pytest.mark.skipif(not os.path.isdir("/proc/self/fd"), reason="needs /proc")


@needs_proc
def test_a_full_disk_while_writing_metrics_is_located_and_recorded(experiment, monkeypatch,
                                                                   capsys):
    out = experiment.parent / "run"
    _full_disk_for(monkeypatch, out, ("metrics.json",))
    assert run(experiment, out) == 1
    err = capsys.readouterr().err
    assert "metrics.json: No space left on device (ENOSPC)" in err
    assert "internal error" not in err
    data = assert_finished(out, "failed")
    assert "metrics.json" in data["error"] and data["files"] == ["run.mcap", "trace.npz"]


@needs_proc
def test_a_full_disk_for_every_file_keeps_run_json_whole_and_the_first_error(
        experiment, monkeypatch, capsys):
    out = experiment.parent / "run"
    _full_disk_for(monkeypatch, out, ("metrics.json", "run.json"))
    assert run(experiment, out) == 1
    err = capsys.readouterr().err
    # The command's error is the first failure; the run.json that could not follow is
    # reported beside it, never instead of it.
    assert "metrics.json: No space left" in err.strip().splitlines()[-1]
    assert "run.json: No space left" in err and "still says the run is unfinished" in err
    assert record(out)["status"] == "running"  # whole, and honest
    monkeypatch.undo()  # space freed: the directory is cleared and run again
    assert run(experiment, out) == 2
    assert run(experiment, out, "--overwrite") == 0
    assert_finished(out)


# --- train -----------------------------------------------------------------------------------


def train(experiment: Path, out: Path, *extra: str) -> int:
    return lab_main(["train", str(experiment), "--out", str(out), *extra])


@needs_fork
def test_train_killed_while_saving_leaves_no_artifact_where_a_run_loads_it(experiment, capsys):
    out = experiment.parent / "trained"

    def patch() -> None:
        import hapticframe.run._train as training

        real = training._save

        def save(components: Any, trained: Any, staging: Path, final: Path) -> Any:
            def cut(directory: Any) -> None:  # the 0-byte weights of a kill -9
                (Path(directory) / "threshold.json").write_text("")
                kill_self()

            for cid in trained:
                components[cid].save = cut
            return real(components, trained, staging, final)

        training._save = save  # type: ignore[assignment]

    killed_at(patch, ["train", str(experiment), "--out", str(out)])
    assert record(out, "train.json")["status"] == "running"
    assert not (out / "contact").exists()
    assert train(experiment, out) == 2
    assert "holds an unfinished training run" in capsys.readouterr().err
    assert train(experiment, out, "--overwrite") == 0
    data = assert_finished(out, name="train.json")
    assert data["files"] == ["contact"] and data["artifacts"] == {"contact": str(out / "contact")}
    assert json.loads((out / "contact" / "threshold.json").read_text())["threshold_n"] > 0


def test_train_whose_save_fails_keeps_no_artifacts_and_records_the_error(experiment,
                                                                         monkeypatch, capsys):
    out = experiment.parent / "trained"
    assert train(experiment, out) == 0
    labplugin = sys.modules["labplugin"]  # imported by --plugin-module

    def full(self: Any, directory: Any) -> None:
        (Path(directory) / "threshold.json").write_text("{")
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(labplugin.ThresholdClassifier, "save", full)
    capsys.readouterr()
    assert train(experiment, out, "--overwrite") == 1
    err = capsys.readouterr().err
    assert "saving contact" in err and "No space left" in err
    data = assert_finished(out, "failed", name="train.json")
    assert data["files"] == [] and "No space left" in data["error"]


def test_overwrite_clears_a_finished_run_of_an_earlier_version(experiment, capsys):
    out = experiment.parent / "old"
    assert run(experiment, out) == 0
    # An earlier version's record: finished, but without the list of its files.
    legacy = {k: v for k, v in record(out).items() if k != "files"}
    (out / "run.json").write_text(json.dumps(legacy), encoding="utf-8")
    (out / "run.mcap").unlink()  # earlier versions recorded no run.mcap
    (out / "notes.txt").write_text("mine", encoding="utf-8")
    assert run(experiment, out, "--overwrite") == 2  # a file it did not write: refused
    assert "notes.txt" in capsys.readouterr().err and (out / "notes.txt").exists()
    (out / "notes.txt").unlink()
    assert run(experiment, out, "--overwrite") == 0
    assert_finished(out)
