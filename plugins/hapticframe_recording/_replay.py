"""Reading one recorded sensor out of a run's ``trace.npz``, with trials and labels.

The layout is the one the run loop writes (``hapticframe.run._streams.TraceRecorder``):

- ``sensor/<id>/timestamps_s`` (n,) and ``sensor/<id>/<channel>`` (n, ...) per sensor, and
  ``sensor/<id>/<channel>/unit`` (a 0-d string); ``sensor/<id>/<channel>/valid`` (n,) bool
  is honoured when present;
- ``robot/<id>/timestamps_s`` (m,) and ``robot/<id>/movement_index`` (m,) per robot step.

A labels file (the ``ground_truth.npz`` a sandbox run writes, or a lab's own annotations)
holds ``timestamps_s`` (k,) and one label array (k,). Files are read with
``allow_pickle=False``: a recording never runs code.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from hapticframe.bounded_io import MAX_RECORDING_BYTES, BoundedReadError, open_regular, read_npz
from hapticframe.kinds import ChannelInfo, SampleBatch

__all__ = [
    "GROUND_TRUTH_FILE",
    "TRACE_FILE",
    "Recording",
    "RecordingError",
    "demo_trace",
    "load_labels",
    "load_recording",
    "read_trace",
    "recording_from_arrays",
]

TRACE_FILE = "trace.npz"
#: What a sandbox run writes beside its trace: the simulator's per-step truth.
GROUND_TRUTH_FILE = "ground_truth.npz"


class RecordingError(ValueError):
    """A recording cannot be replayed: the message names the file and what is missing.

    A ``ValueError``, so that the run reports it as a bad experiment (exit status 2).
    """


@dataclass(frozen=True)
class Recording:
    """One recorded sensor, ready to replay.

    Attributes
    ----------
    source : str
        Where it was read from (for messages).
    timestamps_s : (n,) float64
        Strictly increasing sample times.
    channels : mapping of str to (n, ...) float64
    valid : mapping of str to (n,) bool
        False where a sample is not finite or was recorded invalid.
    info : mapping of str to ChannelInfo
    trial_starts : (t,) intp
        First sample of each trial (exploratory movement); ``trial_starts[0] == 0``.
    """

    source: str
    timestamps_s: NDArray[np.float64]
    channels: Mapping[str, NDArray[np.float64]]
    valid: Mapping[str, NDArray[np.bool_]]
    info: Mapping[str, ChannelInfo]
    trial_starts: NDArray[np.intp]

    def __len__(self) -> int:
        return int(self.timestamps_s.size)

    def batch(self, start: int, stop: int) -> SampleBatch:
        """Samples ``start`` to ``stop`` (exclusive) as a batch."""
        rows = slice(start, stop)
        return SampleBatch(
            self.timestamps_s[rows],
            {name: values[rows] for name, values in self.channels.items()},
            {name: flags[rows] for name, flags in self.valid.items()},
        )

    def trial_bounds(self) -> list[tuple[int, int]]:
        """``(start, stop)`` of every trial, in order."""
        ends = [*self.trial_starts.tolist()[1:], len(self)]
        return list(zip(self.trial_starts.tolist(), ends, strict=True))


def _resolve(path: str | Path, default_name: str, what: str) -> Path:
    target = Path(path).expanduser()
    if target.is_dir():
        target = target / default_name
        if not target.exists():
            raise RecordingError(f"{what}: the directory {path} holds no {default_name}")
    elif not target.exists():
        raise RecordingError(f"{what}: no such file: {target}")
    return target


def _read_npz(
    path: Path,
    what: str,
    wanted: Sequence[str] | None = None,
    max_bytes: int = MAX_RECORDING_BYTES,
) -> dict[str, Any]:
    """The arrays of an ``.npz`` (those whose names start with one of ``wanted``, when
    given), read without pickles from a regular file, their declared sizes checked against
    ``max_bytes`` before decompressing; every failure as a located :class:`RecordingError`."""
    try:
        with open_regular(path) as handle:
            return read_npz(
                handle,
                keep=None if wanted is None else (lambda k: k.startswith(tuple(wanted))),
                max_bytes=max_bytes,
            )
    except FileNotFoundError:
        raise RecordingError(f"{what}: no such file: {path}") from None
    except (BoundedReadError, OSError) as exc:
        raise RecordingError(f"{what}: cannot read {path}: {exc}") from None


def _ids(arrays: Mapping[str, Any], kind: str) -> list[str]:
    """Ids of the components of ``kind`` that have timestamps in a trace."""
    suffix = "/timestamps_s"
    return sorted(
        key[len(kind) + 1 : -len(suffix)]
        for key in arrays
        if key.startswith(f"{kind}/") and key.endswith(suffix) and key.count("/") == 2
    )


def _pick(given: str | None, available: list[str], kind: str, source: str) -> str | None:
    listed = ", ".join(available) or "none"
    if given is not None:
        if given not in available:
            raise RecordingError(
                f"{source} holds no recorded {kind} {given!r} (recorded {kind}s: {listed})"
            )
        return given
    if len(available) > 1:
        raise RecordingError(
            f"{source} holds several {kind}s ({listed}); name one in the config"
        )
    return available[0] if available else None


def _timestamps(value: Any, key: str, source: str, *, strict: bool = True) -> NDArray[np.float64]:
    t = np.asarray(value)
    if t.ndim != 1 or t.dtype.kind not in "biuf":
        raise RecordingError(f"{source}: {key!r} must be a 1-D numeric array, got {t.dtype} "
                             f"of shape {t.shape}")
    t = t.astype(np.float64)
    bad = np.flatnonzero(~np.isfinite(t))
    if bad.size:
        raise RecordingError(
            f"{source}: {key!r} row {int(bad[0])} is {t[bad[0]]:g}; times must be finite"
        )
    steps = np.diff(t)
    back = np.flatnonzero(steps <= 0 if strict else steps < 0)
    if back.size:
        order = "strictly increasing" if strict else "in time order"
        row = int(back[0]) + 1
        raise RecordingError(
            f"{source}: {key!r} is not {order}: row {row} is {t[row]:g} after {t[row - 1]:g}"
        )
    return t


def _channel(arrays: Mapping[str, Any], key: str, n: int, source: str) -> NDArray[np.float64]:
    value = np.asarray(arrays[key])
    if value.ndim == 0 or value.shape[0] != n:
        raise RecordingError(
            f"{source}: {key!r} has shape {value.shape}, expected {n} rows (one per timestamp)"
        )
    if value.dtype.kind not in "biuf":
        what = "complex" if value.dtype.kind == "c" else "not numeric"
        raise RecordingError(
            f"{source}: {key!r} is {what} ({value.dtype}); a recording holds real numbers"
        )
    return value.astype(np.float64)


def _sample_valid(values: NDArray[np.float64]) -> NDArray[np.bool_]:
    """True where every value of a sample is finite."""
    flat = values.reshape(values.shape[0], -1)
    return np.asarray(np.isfinite(flat).all(axis=1), dtype=np.bool_)


def _held_index(times: NDArray[np.float64], at: NDArray[np.float64]) -> NDArray[np.intp]:
    """Index of the latest ``times`` at or before each of ``at`` (-1 before the first)."""
    return np.searchsorted(times, at, side="right") - 1


def load_labels(
    path: str | Path, key: str = "state"
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Label times and values from an ``.npz`` (or a run directory's ``ground_truth.npz``).

    Raises
    ------
    RecordingError
        When the file or one of ``timestamps_s`` and ``key`` is missing or malformed.
    """
    target = _resolve(path, GROUND_TRUTH_FILE, "labels")
    source = str(target)
    arrays = _read_npz(target, "labels")
    for needed in ("timestamps_s", key):
        if needed not in arrays:
            raise RecordingError(
                f"labels: {source} holds no {needed!r} (arrays: {', '.join(sorted(arrays))}); "
                "set labels_key to the label array's name"
            )
    t = _timestamps(arrays["timestamps_s"], "timestamps_s", source)
    values = np.asarray(arrays[key])
    if values.shape != t.shape:
        raise RecordingError(
            f"labels: {source}: {key!r} has shape {values.shape}, expected {t.shape} "
            "(one label per timestamp)"
        )
    if values.dtype.kind not in "biuf":
        what = "complex" if values.dtype.kind == "c" else "not numeric"
        raise RecordingError(f"labels: {source}: {key!r} is {what} ({values.dtype})")
    labels = values.astype(np.float64)
    # Labels are class indices (the sandbox: 0 free, 1 jamming, 2 contact).
    bad = np.flatnonzero(~np.isfinite(labels) | (labels < 0) | (labels != np.round(labels)))
    if bad.size:
        row = int(bad[0])
        raise RecordingError(
            f"labels: {source}: {key!r} row {row} is {labels[row]:g}; labels are class "
            "indices (whole numbers from 0)"
        )
    return t, labels


def recording_from_arrays(
    arrays: Mapping[str, Any],
    *,
    source: str,
    component: str | None = None,
    channels: Sequence[str] | None = None,
    robot: str | None = None,
    split_movements: bool = True,
    labels: tuple[NDArray[np.float64], NDArray[np.float64]] | None = None,
    label_channel: str = "label",
    unlabelled: str = "invalid",
    rate_hz: float | None = None,
) -> Recording:
    """One sensor of a trace's arrays as a :class:`Recording` (see :func:`load_recording`)."""
    sensor = _pick(component, _ids(arrays, "sensor"), "sensor", source)
    if sensor is None:
        raise RecordingError(f"{source} holds no recorded sensor")
    prefix = f"sensor/{sensor}/"
    t = _timestamps(arrays[prefix + "timestamps_s"], prefix + "timestamps_s", source)
    recorded = sorted(
        key[len(prefix):] for key in arrays
        if key.startswith(prefix) and key.count("/") == 2 and key != prefix + "timestamps_s"
    )
    names = list(channels) if channels is not None else recorded
    if not names:
        raise RecordingError(f"{source}: sensor {sensor!r} recorded no channels")
    values: dict[str, NDArray[np.float64]] = {}
    valid: dict[str, NDArray[np.bool_]] = {}
    units: dict[str, str] = {}
    for name in names:
        if name not in recorded:
            raise RecordingError(
                f"{source}: sensor {sensor!r} recorded no channel {name!r} "
                f"(channels: {', '.join(recorded)})"
            )
        key = prefix + name
        values[name] = _channel(arrays, key, t.size, source)
        unit_key = key + "/unit"
        if unit_key not in arrays:
            raise RecordingError(f"{source} holds no {unit_key!r}: the channel's unit is unknown")
        units[name] = str(np.asarray(arrays[unit_key]))
        flags = _sample_valid(values[name])
        if key + "/valid" in arrays:
            recorded_flags = np.asarray(arrays[key + "/valid"])
            if recorded_flags.shape != t.shape:
                raise RecordingError(
                    f"{source}: {key + '/valid'!r} has shape {recorded_flags.shape}, "
                    f"expected {t.shape}"
                )
            flags &= recorded_flags.astype(bool)
        valid[name] = flags

    if labels is not None:
        if label_channel in values:
            raise RecordingError(
                f"{source}: label_channel {label_channel!r} is also a recorded channel of "
                f"sensor {sensor!r}; choose another name"
            )
        label_t, label_values = labels
        held = _held_index(label_t, t)
        label = np.where(held >= 0, label_values[np.maximum(held, 0)], np.nan)
        if unlabelled == "drop":
            keep = held >= 0
            if not keep.any():
                raise RecordingError(
                    f"{source}: every sample of sensor {sensor!r} precedes the first label"
                )
            t, label = t[keep], label[keep]
            values = {k: v[keep] for k, v in values.items()}
            valid = {k: v[keep] for k, v in valid.items()}
        values[label_channel] = label
        valid[label_channel] = np.isfinite(label)
        units[label_channel] = "1"

    rate = rate_hz
    if rate is None:
        if t.size < 2:
            raise RecordingError(
                f"{source}: sensor {sensor!r} has {t.size} sample(s), too few to tell its "
                "rate; set rate_hz"
            )
        # Nine significant digits: recorded times k * dt carry rounding noise far below
        # that, which would otherwise show in the rate (100.00000000000213 Hz).
        rate = float(f"{1.0 / float(np.median(np.diff(t))):.9g}")
    info = {
        name: ChannelInfo(shape=tuple(v.shape[1:]), unit=units[name], rate_hz=rate)
        for name, v in values.items()
    }
    return Recording(
        source=source,
        timestamps_s=t,
        channels=values,
        valid=valid,
        info=info,
        trial_starts=_trial_starts(arrays, t, robot, split_movements, source),
    )


def _trial_starts(
    arrays: Mapping[str, Any],
    t: NDArray[np.float64],
    robot: str | None,
    split_movements: bool,
    source: str,
) -> NDArray[np.intp]:
    """First sample of each exploratory movement of the recorded robot (just 0 without one)."""
    single = np.zeros(min(1, t.size), dtype=np.intp)
    if not split_movements:
        return single
    rid = _pick(robot, _ids(arrays, "robot"), "robot", source)
    if rid is None:
        return single
    index_key = f"robot/{rid}/movement_index"
    if index_key not in arrays:
        raise RecordingError(f"{source} holds no {index_key!r}: the movements are unknown")
    times_key = f"robot/{rid}/timestamps_s"
    robot_t = _timestamps(arrays[times_key], times_key, source, strict=False)
    movement = np.asarray(arrays[index_key])
    if movement.shape != robot_t.shape or not np.issubdtype(movement.dtype, np.integer):
        raise RecordingError(
            f"{source}: {index_key!r} must be integers of shape {robot_t.shape}, got "
            f"{movement.dtype} of shape {movement.shape}"
        )
    if robot_t.size == 0 or t.size == 0:
        return single
    # A sample belongs to the movement of the latest robot step at or before it; samples
    # before the first step (a device streaming before the robot moved) to the first.
    of_sample = movement[np.maximum(_held_index(robot_t, t), 0)]
    changes = np.flatnonzero(of_sample[1:] != of_sample[:-1]) + 1
    return np.concatenate([[0], changes]).astype(np.intp)


def read_trace(path: str | Path) -> tuple[dict[str, Any], str]:
    """The sensor and robot arrays of a ``trace.npz`` (or a run directory's), and the
    file's path for messages; a :class:`RecordingError` when it cannot be read."""
    target = _resolve(path, TRACE_FILE, "recording")
    return _read_npz(target, "recording", ["sensor/", "robot/"]), str(target)


def load_recording(
    path: str | Path,
    *,
    component: str | None = None,
    channels: Sequence[str] | None = None,
    robot: str | None = None,
    split_movements: bool = True,
    labels: str | Path | None = None,
    labels_key: str = "state",
    label_channel: str = "label",
    unlabelled: str = "invalid",
    rate_hz: float | None = None,
) -> Recording:
    """Read one recorded sensor from a ``trace.npz`` (or a run directory holding one).

    Parameters
    ----------
    path : str or Path
        The trace file, or the run directory.
    component : str, optional
        The recorded sensor's id; None takes the only sensor in the trace.
    channels : sequence of str, optional
        The channels to read; None reads all.
    robot : str, optional
        The recorded robot whose ``movement_index`` splits the trials; None takes the only
        robot in the trace; without a robot the recording is one trial.
    split_movements : bool
        False keeps one trial.
    labels : str or Path, optional
        An ``.npz`` with ``timestamps_s`` and ``labels_key``, or a run directory (its
        ``ground_truth.npz``). Each sample gets the latest label at or before its time, in
        the channel ``label_channel`` (unit ``"1"``); a sample before the first label is NaN
        and invalid, or left out with ``unlabelled="drop"``.
    rate_hz : float, optional
        The rate to declare; None takes one over the median recorded sample period.

    Raises
    ------
    RecordingError
        When a file or an array is missing or malformed (the message names which).
    """
    arrays, source = read_trace(path)
    label_arrays = None if labels is None else load_labels(labels, labels_key)
    return recording_from_arrays(
        arrays,
        source=source,
        component=component,
        channels=channels,
        robot=robot,
        split_movements=split_movements,
        labels=label_arrays,
        label_channel=label_channel,
        unlabelled=unlabelled,
        rate_hz=rate_hz,
    )


def demo_trace() -> dict[str, NDArray[Any]]:
    """A small trace in the run loop's layout: three movements of a 2-D wrist force at 100 Hz.

    The robot ``arm`` makes three movements of 0.6 s; the sensor ``wrist`` reads plate drag
    (about 15 N against the motion) with a deterministic ripple, the second movement ends in
    a jamming surge, and one sample of the third is NaN (a lost reading). Used by
    ``demo: true`` (the conformance kit, tutorials).
    """
    per_movement, dt = 60, 0.01
    n = 3 * per_movement
    t = (np.arange(n) + 1) * dt
    movement = np.repeat(np.arange(3), per_movement)
    phase = np.arange(n) % per_movement
    drag = 15.0 * (1.0 + 0.05 * np.sin(2.0 * np.pi * phase / 12.0))
    surge = np.where(movement == 1, 2.5 * np.maximum(phase - 40.0, 0.0) ** 1.5, 0.0)
    force = np.column_stack([-(drag + surge), 0.4 * np.cos(2.0 * np.pi * phase / 17.0)])
    force[2 * per_movement + 25] = np.nan
    return {
        "robot/arm/timestamps_s": t,
        "robot/arm/movement_index": movement.astype(np.int64),
        "sensor/wrist/timestamps_s": t,
        "sensor/wrist/force_n": force,
        "sensor/wrist/force_n/unit": np.array("N"),
    }
