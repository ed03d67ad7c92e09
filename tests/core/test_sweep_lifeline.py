"""A killed sweep leaves nothing behind (issue 26 §7): its fork server, workers and resource
tracker end with it, and the pipes its output is read through close."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
import uuid
from pathlib import Path

import pytest

from hapticframe.sweep import _lifeline

from .test_overrides import TINY

ROOT = Path(__file__).resolve().parents[2]

pytestmark = pytest.mark.skipif(not Path("/proc/self/environ").exists(),
                                reason="finds the sweep's processes through /proc")

#: Generous bounds for a loaded 2-core machine; the fix takes well under a second.
START_S = 60.0
GONE_S = 30.0


def _tagged(tag: str) -> dict[int, str]:
    """``{pid: command line}`` of the running (not zombie) processes that carry ``tag`` in
    their environment: the sweep and everything it started, wherever they were reparented."""
    found: dict[int, str] = {}
    marker = f"HAPTICFRAME_TEST_TAG={tag}".encode()
    for entry in os.listdir("/proc"):
        if not entry.isdigit():
            continue
        try:
            with open(f"/proc/{entry}/environ", "rb") as environ:
                if marker not in environ.read().split(b"\0"):
                    continue
            with open(f"/proc/{entry}/cmdline", "rb") as cmdline:
                found[int(entry)] = cmdline.read().replace(b"\0", b" ").decode(errors="replace")
        except OSError:  # ended meanwhile, or a zombie (no environment to read)
            continue
    return found


def _kill_all(pids: dict[int, str]) -> None:
    for pid in pids:
        try:
            os.kill(pid, signal.SIGKILL)
        except OSError:
            pass


def test_a_sweep_killed_while_its_pipes_are_read_leaves_nothing(tmp_path: Path) -> None:
    (tmp_path / "tiny.yaml").write_text(TINY, encoding="utf-8")
    tag = uuid.uuid4().hex
    env = dict(os.environ, HAPTICFRAME_TEST_TAG=tag, OMP_NUM_THREADS="1")
    sweep = subprocess.Popen(
        [sys.executable, "-m", "hapticframe", "sweep", str(tmp_path / "tiny.yaml"),
         "--vary", "run.max_movements=1,3,4", "--trials", "3", "--workers", "1",
         "--out", str(tmp_path / "sweep")],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, env=env, cwd=ROOT)
    try:
        # The sweep, its resource tracker, the fork server and a worker.
        deadline = time.monotonic() + START_S
        while len(_tagged(tag)) < 4 and time.monotonic() < deadline and sweep.poll() is None:
            time.sleep(0.1)
        started = _tagged(tag)
        assert len(started) >= 4 and sweep.poll() is None, started
        assert any("forkserver" in line for line in started.values()), started

        sweep.send_signal(signal.SIGKILL)
        # As subprocess.run(capture_output=True) does: read both pipes to their end, and
        # only then reap the process (a zombie until then).
        try:
            sweep.communicate(timeout=GONE_S)
        except subprocess.TimeoutExpired:
            pytest.fail(f"the pipes were still open {GONE_S:g} s after the kill, held by "
                        f"{_tagged(tag)}")
        deadline = time.monotonic() + GONE_S
        while _tagged(tag) and time.monotonic() < deadline:
            time.sleep(0.1)
        assert _tagged(tag) == {}
    finally:
        _kill_all(_tagged(tag))
        if sweep.poll() is None:
            sweep.kill()
        sweep.wait(10)


def _zombie() -> subprocess.Popen[bytes]:
    """A child that has ended and is not reaped yet."""
    child = subprocess.Popen([sys.executable, "-c", "pass"])
    deadline = time.monotonic() + START_S
    while time.monotonic() < deadline:
        with open(f"/proc/{child.pid}/stat", "rb") as stat:
            if stat.read().rsplit(b")", 1)[1].split()[0] == b"Z":
                return child
        time.sleep(0.05)
    child.kill()
    pytest.fail("the child did not end")


@pytest.mark.parametrize("pidfd", [True, False], ids=["pidfd", "proc"])
def test_a_zombie_counts_as_gone(monkeypatch: pytest.MonkeyPatch, pidfd: bool) -> None:
    if not pidfd:
        monkeypatch.delattr(os, "pidfd_open", raising=False)
    assert _lifeline.process_alive(os.getpid())
    child = _zombie()
    try:
        assert os.path.exists(f"/proc/{child.pid}")
        os.kill(child.pid, 0)  # what the old check asked: the id exists
        assert not _lifeline.process_alive(child.pid)
        seen: list[int] = []
        watcher = _lifeline.watch_process(child.pid, lambda: seen.append(1), poll_s=0.05)
        watcher.join(GONE_S)
        assert seen == [1]
    finally:
        child.wait()
    # Reaped: gone too, and a watcher says so at once.
    assert not _lifeline.process_alive(child.pid)
    seen.clear()
    _lifeline.watch_process(child.pid, lambda: seen.append(2)).join(GONE_S)
    assert seen == [2]


def test_a_running_process_is_watched_until_it_ends() -> None:
    child = subprocess.Popen([sys.executable, "-c", "import sys; sys.stdin.read()"],
                             stdin=subprocess.PIPE)
    seen: list[int] = []
    watcher = _lifeline.watch_process(child.pid, lambda: seen.append(1), poll_s=0.05)
    time.sleep(0.3)
    assert seen == [] and watcher.is_alive()
    assert child.stdin is not None
    child.stdin.close()
    watcher.join(GONE_S)
    assert seen == [1]
    child.wait()
