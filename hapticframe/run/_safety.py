"""Safety, the same for every robot: the run loop's force limit and stalled force stream,
and stopping every robot when a run is interrupted or a device fails.

The run loop (:mod:`hapticframe.run._loop`) asks a :class:`SafetyMonitor` after each committed
tick whether to halt the robot, and whether a look-ahead batch must be replayed one step at
a time before it is committed (so a halt comes at the same step with or without look-ahead);
it refuses a movement no workspace can start (:data:`OUTSIDE_WORKSPACE`) before it begins
one. :func:`stop_robots` is what :mod:`hapticframe.run._run` calls on a
:class:`~hapticframe.devices.DeviceError`, SIGINT or SIGTERM, before anything else is
released.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from hapticframe._config import RunSettings
from hapticframe.kinds import Component, Device, Robot, RobotState, SampleBatch
from hapticframe.run._dataflow import Dataflow
from hapticframe.run._watchdog import StallWatchdog

__all__ = ["FORCE_LIMIT", "FORCE_STREAM_STALLED", "OUTSIDE_WORKSPACE", "SafetyMonitor",
           "stop_robots"]

#: Halt reasons of the run loop's safety checks (``MovementResult.halt_reason``).
FORCE_LIMIT = "force_limit"
FORCE_STREAM_STALLED = "force_stream_stalled"
OUTSIDE_WORKSPACE = "outside_workspace"

#: Slack on time comparisons: a difference of step times is not exact in floating point.
_EPS_S = 1e-9


class SafetyMonitor:
    """Watches the force samples a closed loop commits, movement by movement.

    - Force limit (``run.force_limit_n``): the first valid sample of a force channel above
      it halts the robot in the tick that commits it. The halt's latency is the number of
      robot steps (control periods) from the sample's timestamp to the robot's state when
      the halt is commanded; each halt is appended to ``halts`` (``run.json`` details), the
      largest latency becomes ``halt_latency_samples_max`` in ``metrics.json``.
    - Stalled stream (``run.force_stall_s``, runs that stream a force): no valid sample on
      one of the force streams the classifiers consume (``Dataflow.stall_streams``: a force
      observer's output, not only the sensors it reads) for that long, by the robot's state
      timestamps since the movement began or since that stream's last valid sample
      arrived, halts the robot. With ``live`` (a run with a
      live device) a :class:`~hapticframe.run._watchdog.StallWatchdog` also watches it on
      the host's clock from a thread, so that a tick stuck in a device call cannot stop the
      check: :meth:`close` stops it.
    """

    def __init__(
        self, settings: RunSettings, flow: Dataflow, halts: list[dict[str, Any]],
        live: bool = False,
    ) -> None:
        self.flow = flow
        self.limit_n = settings.force_limit_n
        # The dataflow notes the first sample above the limit as it commits samples; the
        # limit itself lives here (one home), handed to the dataflow that reports to us.
        flow.force_limit_n = self.limit_n
        self.stall_s = settings.force_stall_s if flow.stall_streams else None
        self.halts = halts
        self.watchdog = (
            StallWatchdog(self.stall_s, self._watchdog_halted).start()
            if live and self.stall_s is not None else None
        )
        self._robot: Robot | None = None
        self._index = 0
        self._rate_hz = 1.0
        # Per watched stream: robot time of its latest valid sample's arrival, its count.
        streams = len(flow.stall_streams)
        self._ref_t = [-math.inf] * streams
        self._seen = [0] * streams
        self._batch_ref_t = [-math.inf] * streams

    @property
    def enabled(self) -> bool:
        return self.limit_n is not None or self.stall_s is not None

    def begin(self, robot: Robot, index: int) -> None:
        """A movement has begun: the stall clock starts from the robot's state now."""
        self._robot, self._index = robot, index
        self._rate_hz = float(robot.control_rate_hz)
        self._ref_t = [float(robot.state.timestamp_s)] * len(self._seen)
        self._seen = list(self.flow.stall_counts)
        self.flow.force_violation = None
        if self.watchdog is not None:
            self.watchdog.arm(robot)

    def end(self) -> None:
        """The movement's part on the robot of :meth:`begin` is over."""
        if self.watchdog is not None:
            self.watchdog.disarm()

    def close(self) -> None:
        """Stop the watchdog (the loop is over)."""
        if self.watchdog is not None:
            self.watchdog.stop()

    def _watchdog_halted(self, robot: Robot, silent_s: float) -> None:
        self.halts.append({
            "reason": FORCE_STREAM_STALLED, "robot": robot.id, "movement": self._index,
            "robot_time_s": float(robot.state.timestamp_s), "silent_s": silent_s,
            "stall_s": self.stall_s, "by": "watchdog",
        })

    def after_commit(self) -> str:
        """After a committed tick: halt the robot if a safety limit was crossed; returns
        the halt reason (``""`` when the movement may go on)."""
        flow, robot = self.flow, self._robot
        if robot is None:
            return ""
        if flow.force_violation is not None:
            stream = flow.force_violation_stream
            sample_t, force_n = flow.take_force_violation() or (math.nan, math.nan)
            now = float(robot.state.timestamp_s)
            latency = max(0, round((now - sample_t) * self._rate_hz))
            robot.halt(FORCE_LIMIT)
            self._record(FORCE_LIMIT, now, latency_samples=latency, sample_time_s=sample_t,
                         force_n=force_n, limit_n=self.limit_n, stream=stream)
            return FORCE_LIMIT
        stall_s = self.stall_s
        if stall_s is not None:
            now = float(robot.state.timestamp_s)
            ref_t = self._ref_t
            oldest = min(ref_t)
            fed = False
            for k, seen in enumerate(flow.stall_counts):
                if seen != self._seen[k]:
                    fed = fed or ref_t[k] <= oldest  # the most silent stream spoke
                    self._seen[k] = seen
                    ref_t[k] = now
            if fed and self.watchdog is not None:
                self.watchdog.fed()
            oldest = min(ref_t)
            if now - oldest >= stall_s - _EPS_S:
                robot.halt(FORCE_STREAM_STALLED)
                cid, channel = flow.stall_streams[ref_t.index(oldest)]
                self._record(FORCE_STREAM_STALLED, now, silent_s=now - oldest,
                             stall_s=stall_s, stream=f"{cid}/{channel}")
                return FORCE_STREAM_STALLED
        return ""

    def batch_needs_replay(
        self, states: Sequence[RobotState], outputs: Mapping[str, SampleBatch]
    ) -> bool:
        """Whether a look-ahead batch (not yet committed) may hold a safety halt, so that
        it must be rewound and replayed one step at a time: a valid force sample above the
        limit, or a stretch of the stall time without a valid sample (a sample counts from
        the first step at or after its timestamp, as a simulated sensor delivers it)."""
        if not self.enabled or not states:
            return False
        times, norms = self.flow.valid_force(outputs)
        if self.limit_n is not None and norms.size and float(norms.max()) > self.limit_n:
            return True
        stall_s = self.stall_s
        if stall_s is None:
            return False
        step_t = np.fromiter((s.timestamp_s for s in states), dtype=np.float64, count=len(states))
        stalls = False
        for k, times in enumerate(self.flow.stall_arrivals(outputs)):
            arrivals = np.zeros(len(step_t), dtype=bool)
            if times.size:
                last = len(step_t) - 1
                arrivals[np.minimum(np.searchsorted(step_t, times - _EPS_S), last)] = True
            ref_t = self._ref_t[k]
            refs = np.maximum(np.maximum.accumulate(np.where(arrivals, step_t, ref_t)), ref_t)
            self._batch_ref_t[k] = float(refs[-1])
            stalls = stalls or bool(np.any(step_t - refs >= stall_s - _EPS_S))
        return stalls

    def batch_committed(self) -> None:
        """A look-ahead batch that :meth:`batch_needs_replay` passed was committed."""
        self._ref_t = [max(a, b) for a, b in zip(self._ref_t, self._batch_ref_t, strict=True)]
        self._seen = list(self.flow.stall_counts)

    def _record(self, reason: str, robot_time_s: float, **extra: Any) -> None:
        robot = self._robot
        self.halts.append({
            "reason": reason,
            "robot": robot.id if robot is not None else "",
            "movement": self._index,
            "robot_time_s": robot_time_s,
            **extra,
        })


def stop_robots(
    components: Mapping[str, Component], reason: str
) -> tuple[list[str], list[str]]:
    """Halt every robot (``reason``) and deactivate those that are devices; the ids halted,
    and what failed while doing so (each robot is tried whatever the others do)."""
    halted: list[str] = []
    failures: list[str] = []
    for cid, component in components.items():
        if not isinstance(component, Robot):
            continue
        try:
            component.halt(reason)
            halted.append(cid)
        except Exception as exc:
            failures.append(f"halting {cid!r} failed: {type(exc).__name__}: {exc}")
        if isinstance(component, Device):
            try:
                component.deactivate()
            except Exception as exc:
                failures.append(f"deactivating {cid!r} failed: {type(exc).__name__}: {exc}")
    return halted, failures
