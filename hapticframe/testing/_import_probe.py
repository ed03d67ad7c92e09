"""Which modules importing a plugin's registration and config modules loads, asked cheaply.

``check_lazy_import`` must import those modules in a fresh interpreter. Starting one per
plugin costs an interpreter start plus numpy and pydantic each time (about a second, most
of the kit's time on a test run). Instead one helper interpreter imports that common base
once and forks a child per question; the child imports the plugin's modules and reports
``sys.modules``. The answer is exact for the names asked about as long as none of them is
in the helper's base, so a question about such a name (or a platform without ``fork``)
falls back to a fresh interpreter.
"""

from __future__ import annotations

import atexit
import json
import os
import select
import subprocess
import sys
from collections.abc import Iterable

__all__ = ["modules_loaded_by"]

#: Seconds one question may take before the kit gives up (a hang guard, as before).
_TIMEOUT_S = 120.0

# What every plugin's registration and config modules import anyway: the spec records,
# the config base class (pydantic) and the records (numpy).
_BASE = "import hapticframe.kinds\nfrom hapticframe import PluginConfig, SensorSpec, hookimpl\n"

_SERVER = _BASE + """\
import importlib, json, os, sys, traceback
reply_to = sys.stdout
print(json.dumps(sorted(sys.modules)), file=reply_to, flush=True)
for line in sys.stdin:
    modules = json.loads(line)
    read_end, write_end = os.pipe()
    pid = os.fork()
    if pid == 0:
        os.close(read_end)
        os.dup2(os.open(os.devnull, os.O_WRONLY), 1)  # a module's prints stay out of replies
        try:
            for name in modules:
                importlib.import_module(name)
            answer = {"modules": sorted(sys.modules)}
        except BaseException:
            answer = {"error": traceback.format_exc()}
        with os.fdopen(write_end, "w") as pipe:
            json.dump(answer, pipe)
        os._exit(0)
    os.close(write_end)
    with os.fdopen(read_end) as pipe:
        data = pipe.read()
    os.waitpid(pid, 0)
    print(data or json.dumps({"error": "the import probe's child died"}), file=reply_to, flush=True)
"""

_FRESH = """\
import importlib, json, sys
for name in json.loads(sys.argv[1]):
    importlib.import_module(name)
print(json.dumps(sorted(sys.modules)))
"""


class _Probe:
    """The helper interpreter: started on first use, ended at exit."""

    def __init__(self) -> None:
        # One BLAS thread: the helper forks, and a forked child has only the forking thread.
        env = {**os.environ, "OPENBLAS_NUM_THREADS": "1", "OMP_NUM_THREADS": "1",
               "MKL_NUM_THREADS": "1"}
        self.process = subprocess.Popen(
            [sys.executable, "-c", _SERVER], stdin=subprocess.PIPE, stdout=subprocess.PIPE,
            stderr=subprocess.DEVNULL, text=True, env=env,
        )
        self.base = frozenset(json.loads(self._reply()))

    def _reply(self) -> str:
        stdout = self.process.stdout
        assert stdout is not None
        ready, _, _ = select.select([stdout], [], [], _TIMEOUT_S)
        line = stdout.readline() if ready else ""
        if not line:
            self.close()
            raise RuntimeError("the import probe did not answer")
        return line

    def ask(self, modules: tuple[str, ...]) -> dict[str, object]:
        stdin = self.process.stdin
        assert stdin is not None
        stdin.write(json.dumps(list(modules)) + "\n")
        stdin.flush()
        answer: dict[str, object] = json.loads(self._reply())
        return answer

    def close(self) -> None:
        if self.process.poll() is None:
            self.process.kill()
        self.process.wait()


_probe: _Probe | None = None
#: Answers by (modules, asked of the probe?): the files do not change under a run.
_cache: dict[tuple[tuple[str, ...], bool], frozenset[str]] = {}


def _shared_probe() -> _Probe | None:
    global _probe
    if _probe is not None and _probe.process.poll() is None:
        return _probe
    _probe = None
    if not hasattr(os, "fork"):
        return None
    try:
        _probe = _Probe()
    except (OSError, RuntimeError, ValueError):
        return None
    atexit.register(_probe.close)
    return _probe


def _fresh_interpreter(modules: tuple[str, ...]) -> frozenset[str]:
    proc = subprocess.run(
        [sys.executable, "-c", _FRESH, json.dumps(list(modules))],
        capture_output=True, text=True, timeout=_TIMEOUT_S, check=False,
    )
    if proc.returncode != 0:
        raise ImportError(proc.stderr.strip()[-500:])
    return frozenset(json.loads(proc.stdout.strip().splitlines()[-1]))


def _probed(probe: _Probe, modules: tuple[str, ...]) -> frozenset[str] | None:
    """The probe's answer, or None when the probe failed (not the import)."""
    try:
        answer = probe.ask(modules)
    except (OSError, RuntimeError, ValueError):
        return None
    if "error" in answer:
        raise ImportError(str(answer["error"]).strip()[-500:])
    loaded = answer.get("modules")
    if not isinstance(loaded, list):
        return None  # a garbled answer: the probe failed
    return frozenset(str(name) for name in loaded)


def modules_loaded_by(modules: Iterable[str], watched: Iterable[str]) -> frozenset[str]:
    """The ``watched`` module names that importing ``modules`` (in order) loads.

    Asked of the helper interpreter when none of ``watched`` is in its base, else (or when
    the helper fails) of a fresh interpreter; answers are cached for the process.

    Raises
    ------
    ImportError
        When importing ``modules`` fails; the message ends with the traceback's tail.
    """
    key, watched = tuple(modules), frozenset(watched)
    probe = _shared_probe()
    if probe is not None and not watched & probe.base:
        if (key, True) not in _cache:
            answer = _probed(probe, key)
            if answer is not None:
                _cache[key, True] = answer
        if (key, True) in _cache:
            return _cache[key, True] & watched
    if (key, False) not in _cache:
        _cache[key, False] = _fresh_interpreter(key)
    return _cache[key, False] & watched
