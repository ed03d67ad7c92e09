"""What flows between the components of a run, kept and joined: the trace recorder
(``trace.npz``), a robot's pose history (where each sample was taken), batch merging and the
aligner that joins inputs on different clocks. :class:`~hapticframe.run._dataflow.Dataflow`
uses them to move the samples through the chain.
"""

from __future__ import annotations

import math
import zipfile
from collections import defaultdict
from collections.abc import Sequence
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from hapticframe._errors import RunError
from hapticframe.kinds import (
    InputAlignment,
    RobotState,
    SampleBatch,
    concatenate_batches,
)

__all__ = ["MAX_KEPT_S", "InputAligner", "PoseHistory", "TraceRecorder", "merge_batches"]


class TraceRecorder:
    """Collects arrays per key and writes them to one ``.npz`` (no pickles).

    A closed loop records a few scalars per robot step; :meth:`add_row` keeps those as
    Python values and builds one array per key when the trace is read, instead of a tiny
    array per step. Rows and arrays added under the same key stay in call order.
    """

    def __init__(self) -> None:
        self._parts: dict[str, list[np.ndarray]] = defaultdict(list)
        self._rows: dict[str, list[Any]] = {}
        self._fixed: dict[str, np.ndarray] = {}

    def add(self, key: str, array: np.ndarray) -> None:
        if key in self._rows:
            self._flush_rows(key)
        self._parts[key].append(np.asarray(array))

    def add_row(self, key: str, value: Any) -> None:
        """Append one row: a scalar, or a sequence of scalars for a row of a 2-D entry.

        Equivalent to ``add(key, np.array([value]))`` for plain scalars and float arrays'
        rows: consecutive rows become one array when the trace is read, its dtype inferred
        from all of them at once.
        """
        rows = self._rows.get(key)
        if rows is None:
            self._parts.setdefault(key, [])  # the key keeps its place in the trace
            rows = self._rows[key] = []
        rows.append(value)

    def _flush_rows(self, key: str) -> None:
        rows = self._rows.pop(key)
        self._parts[key].append(np.array(rows))

    def set(self, key: str, array: np.ndarray) -> None:
        self._fixed[key] = np.asarray(array)

    def arrays(self) -> dict[str, np.ndarray]:
        for key in list(self._rows):
            self._flush_rows(key)
        out = {k: np.concatenate(v) if v else np.empty(0) for k, v in self._parts.items()}
        # Keep the joined arrays: reading the trace again (the run's evaluation, then the
        # saved file) does not concatenate every part a second time.
        for key, array in out.items():
            if len(self._parts[key]) > 1:
                self._parts[key] = [array]
        out.update(self._fixed)
        return out

    def save(self, path: str) -> None:
        """Write every entry to ``path`` as a compressed ``.npz`` (``np.load`` reads it).

        The layout of ``np.savez_compressed``, at zlib level 1: a closed loop's trace
        compresses to nearly the same size (within 1 %) two to four times faster.
        """
        arrays = self.arrays()
        for key, value in arrays.items():
            if value.dtype == object:  # pragma: no cover - guarded by construction
                raise RunError(f"trace entry {key!r} is not a plain array")
        if not path.endswith(".npz"):
            path += ".npz"  # as np.savez names the file
        with zipfile.ZipFile(
            path, mode="w", compression=zipfile.ZIP_DEFLATED, compresslevel=1, allowZip64=True
        ) as archive:
            for key, value in arrays.items():
                with archive.open(f"{key}.npy", mode="w", force_zip64=True) as member:
                    np.lib.format.write_array(member, value, allow_pickle=False)


class PoseHistory:
    """Fingertip poses over time, interpolated at the times of classifier outputs.

    Poses are kept column by column in growable arrays, so interpolation reads contiguous
    slices and copies nothing per tick. A query at or after the latest pose (a closed loop
    classifies the sample of the step just taken) is answered from the latest pose without
    interpolating: ``np.interp`` returns exactly that pose there.
    """

    def __init__(self) -> None:
        self._n = 0
        # t, x, y, heading (unwrapped), depth
        self._columns = [np.empty(256) for _ in range(5)]
        self._latest: tuple[float, float, float, float, float] | None = None
        self._nonfinite_depths = 0

    def __len__(self) -> int:
        return self._n

    def add_state(self, state: RobotState) -> None:
        x, y = state.position_m.tolist()
        self._append(float(state.timestamp_s), x, y, float(state.heading_rad), float(state.depth_m))

    def add(self, t: float, xy: ArrayLike, heading: float, depth: float) -> None:
        x, y = np.asarray(xy, dtype=np.float64).tolist()
        self._append(float(t), x, y, float(heading), float(depth))

    def _append(self, t: float, x: float, y: float, heading: float, depth: float) -> None:
        latest = self._latest
        if latest is not None:
            if t <= latest[0]:
                return  # a repeated or stale pose adds nothing
            # Unwrap so that interpolation never swings through ±pi.
            previous = latest[3]
            heading = previous + (heading - previous + math.pi) % (2 * math.pi) - math.pi
        n = self._n
        columns = self._columns
        if n == len(columns[0]):
            columns = self._columns = [np.concatenate([c, np.empty(n)]) for c in columns]
        columns[0][n] = t
        columns[1][n] = x
        columns[2][n] = y
        columns[3][n] = heading
        columns[4][n] = depth
        self._latest = (t, x, y, heading, depth)
        if not math.isfinite(depth):
            self._nonfinite_depths += 1
        self._n = n + 1

    def add_batch(self, batch: SampleBatch) -> None:
        """Poses from a sensor's ``position_m`` (and optional heading/depth) channels."""
        pos = batch.channels["position_m"]
        if "heading_rad" in batch.channels:
            heading = batch.channels["heading_rad"].reshape(-1)
        else:
            latest = self._latest
            prev = latest[1:3] if latest is not None else (pos[0] if len(pos) else np.zeros(2))
            steps = np.diff(np.vstack([prev, pos]), axis=0)
            heading = np.arctan2(steps[:, 1], steps[:, 0])
        if "depth_m" in batch.channels:
            depth = batch.channels["depth_m"].reshape(-1)
        else:
            depth = np.full(len(batch), np.nan)
        for i in range(len(batch)):
            self.add(batch.timestamps_s[i], pos[i], heading[i], depth[i])

    def at(self, times: NDArray[np.float64]) -> tuple[NDArray[np.float64], ...]:
        """Positions ``(n, 2)``, headings ``(n,)`` and depths ``(n,)`` at ``times``.

        Linear interpolation between poses (the first or last pose outside them); depth
        is NaN everywhere once any recorded depth is not finite.
        """
        latest = self._latest
        if latest is None:
            raise RunError("a sensor model needs fingertip poses, but none were recorded yet")
        if len(times) == 1 and times[0] >= latest[0]:
            _, x, y, heading, depth = latest
            if self._nonfinite_depths:
                depth = math.nan
            pose = np.array([[x, y, heading, depth]])  # one allocation, three views
            return pose[:, :2], pose[0, 2:3], pose[0, 3:4]
        n = self._n
        t = self._columns[0][:n]
        xs, ys, headings = (np.interp(times, t, self._columns[k][:n]) for k in (1, 2, 3))
        if self._nonfinite_depths:
            depths = np.full(len(times), np.nan)
        else:
            depths = np.interp(times, t, self._columns[4][:n])
        return np.column_stack([xs, ys]), headings, depths


def merge_batches(
    batches: Sequence[SampleBatch], consumer: str, alignment: InputAlignment | None = None
) -> SampleBatch:
    """Join the batches of several inputs into the one batch ``consumer`` reads.

    With the default (``exact``) alignment the inputs must share timestamps. With
    ``hold`` or ``linear`` (:class:`~hapticframe.kinds.InputAlignment`) every input after
    the first is resampled onto the first input's timestamps, as :class:`InputAligner` does
    tick by tick: the whole recordings at once give what a stream of them gives.
    """
    if len(batches) == 1:
        return batches[0]
    if alignment is None or alignment.method == "exact":
        return _merge_exact(batches, consumer)
    return InputAligner(alignment, consumer).push(batches)


def _merge_exact(batches: Sequence[SampleBatch], consumer: str) -> SampleBatch:
    first = batches[0]
    channels: dict[str, np.ndarray] = {}
    valid: dict[str, np.ndarray] = {}
    for batch in batches:
        if batch.timestamps_s.shape != first.timestamps_s.shape or not np.array_equal(
            batch.timestamps_s, first.timestamps_s
        ):
            raise RunError(
                f"the inputs of {consumer!r} deliver samples at different times; give it "
                "inputs that share a clock, or one input, or let it align its inputs "
                "(Component.input_alignment: hold or linear)"
            )
        for name, array in batch.channels.items():
            if name in channels:
                raise RunError(f"two inputs of {consumer!r} both provide channel {name!r}")
            channels[name] = array
        valid.update(batch.valid)
    return SampleBatch(first.timestamps_s, channels, valid)


#: The longest span of a later input's samples an :class:`InputAligner` keeps, in seconds.
MAX_KEPT_S = 10.0


class InputAligner:
    """Resamples a consumer's later inputs onto its first input's timestamps, tick by tick.

    The dataflow keeps one per consumer whose :attr:`~hapticframe.kinds.Component.
    input_alignment` is ``hold`` or ``linear``; :func:`merge_batches` uses a fresh one for
    whole recordings. Between pushes it keeps, per later input, the samples a future
    timestamp may still need (from the latest one at or before the earliest timestamp still
    to come), and, for ``linear``, the first input's samples that wait for a later sample
    to interpolate towards. Each timestamp is resolved from the same samples however the
    recordings are cut into pushes, so streaming equals batch exactly, provided that when a
    push delivers a sample of the first input, every later input has delivered its samples
    up to that time. A run reads its sensors one after the other, in build order, and
    sensors stamp samples with one host clock, so an input read after the first one is
    ahead of it. (A sample of a later input that comes a push late is used only from then
    on.)
    """

    def __init__(self, alignment: InputAlignment, consumer: str) -> None:
        if alignment.method == "exact":
            raise ValueError("an InputAligner aligns by 'hold' or 'linear', not 'exact'")
        self.alignment = alignment
        self.consumer = consumer
        self.reset()

    def reset(self) -> None:
        """Forget every kept sample (a new stream starts)."""
        self._tails: list[SampleBatch | None] = []
        self._pending: SampleBatch | None = None
        self._last_t = -math.inf

    def checkpoint(self) -> tuple[list[SampleBatch | None], SampleBatch | None, float]:
        """The kept samples (batches are immutable, so no copy is needed)."""
        return list(self._tails), self._pending, self._last_t

    def rewind(self, checkpoint: tuple[list[SampleBatch | None], SampleBatch | None, float]
               ) -> None:
        tails, pending, last_t = checkpoint
        self._tails, self._pending, self._last_t = list(tails), pending, last_t

    def push(self, batches: Sequence[SampleBatch]) -> SampleBatch:
        """The joined batch of the first input's samples that can be resolved so far."""
        primary = batches[0]
        if self._pending is not None and len(self._pending):
            primary = concatenate_batches([self._pending, primary])
        times = primary.timestamps_s
        if len(times):
            self._last_t = max(self._last_t, float(times[-1]))
        while len(self._tails) < len(batches) - 1:
            self._tails.append(None)
        channels: dict[str, np.ndarray] = dict(primary.channels)
        valid: dict[str, np.ndarray] = dict(primary.valid)
        ready = len(times)
        known_inputs: list[SampleBatch] = []
        for k, batch in enumerate(batches[1:]):
            known = _join_tail(self._tails[k], batch)
            known_inputs.append(known)
            values, flags, decided = _resample(known, times, self._last_t, self.alignment)
            for name, array in values.items():
                if name in channels:
                    raise RunError(
                        f"two inputs of {self.consumer!r} both provide channel {name!r}"
                    )
                channels[name] = array
                valid[name] = flags[name]
            if not decided.all():
                ready = min(ready, int(np.argmin(decided)))
        # Keep from the latest sample at or before the earliest timestamp still to come
        # (a pending one, or any after the first input's latest): its lower neighbour.
        horizon = float(times[ready]) if ready < len(times) else self._last_t
        for k, known in enumerate(known_inputs):
            if len(known):
                # A first input that delivers nothing for long (or lags far behind) must not
                # make the others' samples pile up: a sample more than MAX_KEPT_S older than
                # its input's latest is needed by no timestamp a live stream still brings.
                horizon_k = max(horizon, float(known.timestamps_s[-1]) - MAX_KEPT_S)
            else:
                horizon_k = horizon
            first = max(int(np.searchsorted(known.timestamps_s, horizon_k, side="right")) - 1, 0)
            self._tails[k] = known.select(slice(first, None)) if first else known
        self._pending = primary.select(slice(ready, None)) if ready < len(times) else None
        if ready < len(times):
            rows = slice(0, ready)
            return SampleBatch(
                times[rows],
                {name: array[rows] for name, array in channels.items()},
                {name: mask[rows] for name, mask in valid.items()},
            )
        return SampleBatch(times, channels, valid)


def _join_tail(tail: SampleBatch | None, batch: SampleBatch) -> SampleBatch:
    """The kept samples followed by the new ones (a sample not after the kept ones is a
    sensor's repeat and is dropped)."""
    if tail is None or not len(tail):
        return batch
    if not len(batch):
        return tail
    if batch.timestamps_s[0] <= tail.timestamps_s[-1]:
        batch = batch.select(batch.timestamps_s > tail.timestamps_s[-1])
        if not len(batch):
            return tail
    return concatenate_batches([tail, batch])


def _resample(
    source: SampleBatch, times: NDArray[np.float64], last_t: float, alignment: InputAlignment
) -> tuple[dict[str, NDArray[np.float64]], dict[str, NDArray[np.bool_]], NDArray[np.bool_]]:
    """``source``'s channels at ``times``: values, per-channel validity, and which times
    are decided (``linear`` waits for the sample after a time, at most ``max_age_s``)."""
    st = source.timestamps_s
    m, n = len(st), len(times)
    max_age = alignment.max_age_s
    below = np.searchsorted(st, times, side="right") - 1
    seen = below >= 0  # False: before the input's first sample
    lower = np.clip(below, 0, max(m - 1, 0))
    decided = np.ones(n, dtype=bool)
    if m == 0:
        ok = np.zeros(n, dtype=bool)
        weight = upper = None
    else:
        lower_t = st[lower]
        ok = seen & (times - lower_t <= max_age)
        weight = upper = None
        if alignment.method == "linear":
            has_next = seen & (below + 1 < m)
            upper = np.clip(below + 1, 0, m - 1)
            exact = seen & (lower_t == times)
            upper_t = st[upper]
            between = has_next & ~exact
            span = np.where(between, upper_t - lower_t, 1.0)
            weight = np.where(between, (times - lower_t) / span, 0.0)
            decided = ~ok | exact | has_next | (last_t - times > max_age)
            ok = exact | (ok & has_next & (upper_t - times <= max_age))
            upper = np.where(exact, lower, upper)
    values: dict[str, NDArray[np.float64]] = {}
    flags: dict[str, NDArray[np.bool_]] = {}
    for name, array in source.channels.items():
        shape = (n, *array.shape[1:])
        if m == 0:
            values[name] = np.full(shape, np.nan)
            flags[name] = np.zeros(n, dtype=bool)
            continue
        source_valid = source.valid.get(name)
        good = ok if source_valid is None else ok & source_valid[lower]
        if weight is not None and upper is not None:
            if source_valid is not None:
                good = good & source_valid[upper]
            w = weight.reshape((n,) + (1,) * (array.ndim - 1))
            low, high = array[lower], array[upper]
            with np.errstate(invalid="ignore"):
                # A timestamp on a sample takes it as it is (no 0 * inf).
                value = np.where(w == 0.0, low, low + w * (high - low))
        else:
            value = array[lower]
        value[~good] = np.nan
        values[name] = value
        flags[name] = good
    return values, flags, decided
