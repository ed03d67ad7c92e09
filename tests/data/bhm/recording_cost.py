"""CPU time inside the recording: RunRecording's methods and the dataflow's snapshots.

    python tests/data/bhm/recording_cost.py tests/data/bhm/search-10x10.yaml OUT_DIR

Each method is wrapped once (nested calls count in their caller); the wrapper's own cost per
call is measured first and taken off. Prints the run's CPU, the recording's and its share of
the rest, then the split by method (docs/benchmarks.md, the recording's cost).
"""

from __future__ import annotations

import collections
import functools
import sys
import time
from collections.abc import Callable
from typing import Any

from hapticframe import run_experiment, validate_file
from hapticframe.record import _recording
from hapticframe.run import _dataflow

RECORDING_METHODS = (
    "samples", "probabilities", "located", "observations", "robot_state", "movement",
    "event", "later", "health", "configure_snapshots", "snapshot_due", "scene",
    "map_snapshot", "flush_blocks", "sync", "close", "__init__",
)

spent: collections.Counter[str] = collections.Counter()
calls: collections.Counter[str] = collections.Counter()
inside = [False]


def timed(fn: Callable[..., Any], label: str) -> Callable[..., Any]:
    @functools.wraps(fn)
    def wrapper(*args: Any, **kwargs: Any) -> Any:
        if inside[0]:
            return fn(*args, **kwargs)
        inside[0] = True
        start = time.process_time()
        try:
            return fn(*args, **kwargs)
        finally:
            spent[label] += time.process_time() - start
            calls[label] += 1
            inside[0] = False
    return wrapper


def main(experiment_file: str, out_dir: str) -> None:
    recording_class = _recording.RunRecording
    for name in RECORDING_METHODS:
        setattr(recording_class, name, timed(getattr(recording_class, name), name))
    recording_class.now_s = property(timed(recording_class.now_s.fget, "now_s"))  # type: ignore[method-assign,assignment,arg-type]
    for name in ("snapshot_maps", "loop_event"):
        setattr(_dataflow.Dataflow, name, timed(getattr(_dataflow.Dataflow, name), name))
    noop = timed(lambda: None, "noop")
    n = 200_000
    start = time.process_time()
    for _ in range(n):
        noop()
    per_call = (time.process_time() - start) / n
    spent.clear()
    calls.clear()
    experiment = validate_file(experiment_file)
    start = time.process_time()
    run_experiment(experiment, out_dir, overwrite=True, progress=False, echo=lambda _s: None,
                   recording=_recording.open_run_recording)
    total = time.process_time() - start
    net = {k: v - calls[k] * per_call for k, v in spent.items()}
    recording = sum(net.values())
    print(f"run_cpu_s={total:.2f} recording_cpu_s={recording:.2f} "
          f"calls={sum(calls.values())} timer_us_per_call={per_call * 1e6:.2f} "
          f"share_of_rest={recording / (total - recording) * 100:.1f}%")
    for label, seconds in sorted(net.items(), key=lambda kv: -kv[1]):
        print(f"  {label:22s} {seconds:7.3f} s  {calls[label]:7d} calls")


if __name__ == "__main__":
    main(sys.argv[1], sys.argv[2])
