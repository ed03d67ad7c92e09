"""Immutable data records that flow between components.

Every array is float64 unless stated, SI units throughout (REP 103): metres, seconds,
newtons, radians. Records validate their shapes on construction so that a plugin that
emits a malformed record fails where it emits it, not three components downstream.

Records own their arrays: a writable array (or a list) given to a record is copied into a
read-only array, so a caller that later changes its own array cannot change a validated
record. A read-only array is taken as it is, without a copy: by numpy's convention nobody
writes to it (every record array is one, so records hand arrays on to records for free).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from hapticframe.geometry import rotation_matrix_from_wxyz

__all__ = [
    "ChannelInfo",
    "ClassProbabilities",
    "ExploratoryMovement",
    "LocatedMeasurement",
    "MapEstimate",
    "MovementResult",
    "Observations",
    "PhysicalTruth",
    "Region",
    "RobotState",
    "SampleBatch",
    "concatenate_batches",
]

FloatArray = NDArray[np.float64]


_FLOAT64 = np.dtype(np.float64)
_BOOL = np.dtype(np.bool_)


def _owned(value: Any, dtype: np.dtype[Any]) -> Any:
    """``value`` as a read-only array of ``dtype`` that the record owns.

    A read-only array of that dtype is taken as is; anything else is copied, so that the
    caller's writable array and the record never share memory.
    """
    if type(value) is np.ndarray and value.dtype is dtype and not value.flags.writeable:
        return value
    array: np.ndarray[Any, Any] = np.array(value, dtype=dtype)
    array.setflags(write=False)
    return array


def _as_float_array(value: ArrayLike, name: str, ndim: int | None = None) -> FloatArray:
    array: FloatArray = _owned(value, _FLOAT64)
    if ndim is not None and array.ndim != ndim:
        raise ValueError(f"{name} must have {ndim} dimension(s), got shape {array.shape}")
    return array


def _check_rows(name: str, array: np.ndarray, n: int) -> None:
    if array.shape[0] != n:
        raise ValueError(f"{name} has {array.shape[0]} rows, expected {n} (one per timestamp)")


def _clearly_valid_row(row: list[float]) -> bool:
    """True when one row of probabilities passes the checks of :class:`ClassProbabilities`
    with a margin; False sends it to the array checks, which decide and give the message.

    A closed loop classifies one sample per tick, where four numpy reductions cost more
    than the classifier. A finite sum means every entry is finite; the sum's tolerance is
    halved, so that summing in another order than numpy cannot accept a row it rejects.
    """
    total = sum(row)
    return math.isfinite(total) and min(row) >= 0 and max(row) <= 1 and abs(total - 1.0) <= 5e-7


@dataclass(frozen=True)
class ChannelInfo:
    """What one sensor channel carries.

    Parameters
    ----------
    shape : tuple of int
        Shape of one sample (``()`` for a scalar, ``(19,)`` for 19 electrodes).
    unit : str
        SI unit (``"N"``, ``"Pa"``, ``"m"``) or ``"count"`` for raw ADC values, ``"1"`` for
        dimensionless values.
    rate_hz : float
        Nominal sample rate of the channel.
    latency_s : float
        How long after its time stamp a sample may arrive (a device's buffering, a bus's
        delay); 0 for a stream stamped on the run's clock. A closed loop ends the run as no
        result when a stream's latest sample lies further than this plus one control period
        and one sample period from the robot's time (issue 34).
    """

    shape: tuple[int, ...]
    unit: str
    rate_hz: float
    latency_s: float = 0.0


@dataclass(frozen=True)
class SampleBatch:
    """Timestamped samples of named channels: sensor readings or features.

    Parameters
    ----------
    timestamps_s : (n,) float64
        Strictly increasing sample times in seconds.
    channels : mapping of str to (n, ...) float64
        One array per channel; the first axis indexes samples.
    valid : mapping of str to (n,) bool, optional
        Per-channel validity (a corrupted word on a bus, a stale reading). Missing means valid.
    """

    timestamps_s: FloatArray
    channels: Mapping[str, FloatArray]
    valid: Mapping[str, NDArray[np.bool_]] = field(default_factory=dict)

    def __post_init__(self) -> None:
        t = _as_float_array(self.timestamps_s, "timestamps_s", ndim=1)
        object.__setattr__(self, "timestamps_s", t)
        if t.size == 1:  # a closed loop's one-sample batch: no numpy reductions
            if not math.isfinite(t[0]):
                raise ValueError("timestamps_s must be finite")
        elif t.size:
            if not (t[1:] > t[:-1]).all():
                raise ValueError("timestamps_s must be strictly increasing")
            if not np.isfinite(t).all():
                raise ValueError("timestamps_s must be finite")
        channels = {}
        for name, value in self.channels.items():
            # _as_float_array and _check_rows inline: no message is formatted per channel
            # unless a check fails.
            array = _owned(value, _FLOAT64)
            if array.ndim == 0:
                raise ValueError(f"channel {name!r} must have a sample axis")
            if array.shape[0] != t.size:
                _check_rows(f"channel {name!r}", array, t.size)
            channels[name] = array
        valid = {}
        for name, flags in self.valid.items():
            if name not in channels:
                raise ValueError(f"validity given for unknown channel {name!r}")
            mask: NDArray[np.bool_] = _owned(flags, _BOOL)
            if mask.shape != (t.size,):
                raise ValueError(f"valid[{name!r}] must have shape ({t.size},), got {mask.shape}")
            valid[name] = mask
        object.__setattr__(self, "channels", MappingProxyType(channels))
        object.__setattr__(self, "valid", MappingProxyType(valid))

    def __len__(self) -> int:
        return int(self.timestamps_s.size)

    @classmethod
    def empty(cls, channels: Mapping[str, ChannelInfo]) -> SampleBatch:
        """A batch with no samples and the given channel layout."""
        return cls(
            np.empty(0),
            {name: np.empty((0, *info.shape)) for name, info in channels.items()},
        )

    def select(self, rows: slice | NDArray[np.intp] | NDArray[np.bool_]) -> SampleBatch:
        """The samples at ``rows`` (a slice, index array or boolean mask)."""
        return SampleBatch(
            self.timestamps_s[rows],
            {k: v[rows] for k, v in self.channels.items()},
            {k: v[rows] for k, v in self.valid.items()},
        )


def concatenate_batches(batches: Sequence[SampleBatch]) -> SampleBatch:
    """Join consecutive batches of the same channels into one."""
    if not batches:
        raise ValueError("need at least one batch to concatenate")
    names = list(batches[0].channels)
    for batch in batches[1:]:
        if list(batch.channels) != names:
            raise ValueError(f"channel sets differ: {names} vs {list(batch.channels)}")
    valid_names = {k for b in batches for k in b.valid}
    return SampleBatch(
        np.concatenate([b.timestamps_s for b in batches]),
        {k: np.concatenate([b.channels[k] for b in batches]) for k in names},
        {
            k: np.concatenate(
                [b.valid.get(k, np.ones(len(b), dtype=bool)) for b in batches]
            )
            for k in valid_names
        },
    )


@dataclass(frozen=True)
class ClassProbabilities:
    """Interaction or contact state as class probabilities, one row per timestamp.

    Parameters
    ----------
    timestamps_s : (n,) float64
        Times the probabilities refer to (the input's times, less any look-ahead delay).
    probabilities : (n, k) float64
        Rows in [0, 1] that sum to 1.
    classes : tuple of str
        The k class names; by convention ``classes[0]`` is the background state
        ("free movement").
    """

    timestamps_s: FloatArray
    probabilities: FloatArray
    classes: tuple[str, ...]

    def __post_init__(self) -> None:
        t = _as_float_array(self.timestamps_s, "timestamps_s", ndim=1)
        p = _as_float_array(self.probabilities, "probabilities", ndim=2)
        object.__setattr__(self, "timestamps_s", t)
        object.__setattr__(self, "probabilities", p)
        object.__setattr__(self, "classes", tuple(self.classes))
        _check_rows("probabilities", p, t.size)
        if p.shape[1] != len(self.classes):
            raise ValueError(
                f"probabilities have {p.shape[1]} columns for {len(self.classes)} classes"
            )
        # One clearly valid row (a closed loop's tick) skips the array checks below.
        clearly_valid = p.shape[0] == 1 and p.size > 0 and _clearly_valid_row(p[0].tolist())
        if p.size and not clearly_valid:
            if not np.isfinite(p).all():
                raise ValueError("probabilities contain NaN or infinity")
            if p.min() < 0 or p.max() > 1:
                raise ValueError("probabilities must lie in [0, 1]")
            if np.abs(p.sum(axis=1) - 1.0).max() > 1e-6:
                raise ValueError("each row of probabilities must sum to 1")

    def __len__(self) -> int:
        return int(self.timestamps_s.size)

    @property
    def labels(self) -> NDArray[np.intp]:
        """Index of the most probable class per row."""
        labels: NDArray[np.intp] = np.argmax(self.probabilities, axis=1)
        return labels


@dataclass(frozen=True)
class Region:
    """An axis-aligned rectangle in the map plane (metres)."""

    x_min_m: float
    x_max_m: float
    y_min_m: float
    y_max_m: float

    def __post_init__(self) -> None:
        values = (self.x_min_m, self.x_max_m, self.y_min_m, self.y_max_m)
        if not all(np.isfinite(values)):
            raise ValueError("region bounds must be finite")
        if not (self.x_max_m > self.x_min_m and self.y_max_m > self.y_min_m):
            raise ValueError("region must have positive width and height")

    @property
    def size_m(self) -> tuple[float, float]:
        return (self.x_max_m - self.x_min_m, self.y_max_m - self.y_min_m)

    @property
    def center_m(self) -> FloatArray:
        return np.array([(self.x_min_m + self.x_max_m) / 2, (self.y_min_m + self.y_max_m) / 2])

    def contains(self, points_m: ArrayLike, tolerance_m: float = 0.0) -> NDArray[np.bool_]:
        """Which points lie in the region grown by ``tolerance_m`` on every side."""
        p = np.atleast_2d(np.asarray(points_m, dtype=np.float64))
        t = tolerance_m
        return (
            (p[:, 0] >= self.x_min_m - t)
            & (p[:, 0] <= self.x_max_m + t)
            & (p[:, 1] >= self.y_min_m - t)
            & (p[:, 1] <= self.y_max_m + t)
        )

    def grid(self, spacing_m: float) -> tuple[FloatArray, FloatArray]:
        """Cell-centre coordinates ``(xs, ys)`` of a regular grid covering the region."""
        if not spacing_m > 0:
            raise ValueError("spacing_m must be positive")
        nx = max(1, int(np.ceil((self.x_max_m - self.x_min_m) / spacing_m)))
        ny = max(1, int(np.ceil((self.y_max_m - self.y_min_m) / spacing_m)))
        xs = self.x_min_m + (np.arange(nx) + 0.5) * (self.x_max_m - self.x_min_m) / nx
        ys = self.y_min_m + (np.arange(ny) + 0.5) * (self.y_max_m - self.y_min_m) / ny
        return xs, ys


@dataclass(frozen=True, init=False)
class LocatedMeasurement:
    """Classifier output placed in the map plane: the input of a sensor model (Eq. 3.1).

    Parameters
    ----------
    timestamps_s : (n,) float64
    positions_m : (n, 2) float64
        Fingertip position in the map frame.
    headings_rad : (n,) float64
        Direction of motion, counter-clockwise from +x.
    probabilities : (n, k) float64
        Class probabilities, as in :class:`ClassProbabilities`.
    classes : tuple of str
    depth_m : (n,) float64, optional
        Fingertip depth below the free surface; NaN where unknown, and NaN for every row
        when not given (the attribute is always an array).
    """

    timestamps_s: FloatArray
    positions_m: FloatArray
    headings_rad: FloatArray
    probabilities: FloatArray
    classes: tuple[str, ...]
    depth_m: FloatArray

    def __init__(
        self,
        timestamps_s: ArrayLike,
        positions_m: ArrayLike,
        headings_rad: ArrayLike,
        probabilities: ArrayLike,
        classes: Sequence[str],
        depth_m: ArrayLike | None = None,
    ) -> None:
        t = _as_float_array(timestamps_s, "timestamps_s", ndim=1)
        n = t.size
        pos = _as_float_array(positions_m, "positions_m", ndim=2)
        if pos.shape != (n, 2):
            raise ValueError(f"positions_m must have shape ({n}, 2), got {pos.shape}")
        heading = _as_float_array(headings_rad, "headings_rad", ndim=1)
        _check_rows("headings_rad", heading, n)
        depth = _as_float_array(np.full(n, np.nan) if depth_m is None else depth_m,
                                "depth_m", ndim=1)
        _check_rows("depth_m", depth, n)
        # Reuse the probability checks.
        probs = ClassProbabilities(
            t, _as_float_array(probabilities, "probabilities", ndim=2), tuple(classes)
        )
        for name, value in (
            ("timestamps_s", t),
            ("positions_m", pos),
            ("headings_rad", heading),
            ("depth_m", depth),
            ("probabilities", probs.probabilities),
            ("classes", probs.classes),
        ):
            object.__setattr__(self, name, value)

    def __len__(self) -> int:
        return int(self.timestamps_s.size)

    @classmethod
    def _from_checked(
        cls,
        probabilities: ClassProbabilities,
        positions_m: FloatArray,
        headings_rad: FloatArray,
        depth_m: FloatArray,
    ) -> LocatedMeasurement:
        """Place an already validated classifier output, without checking it again.

        For the core's dataflow only: ``probabilities`` passed the checks of
        :class:`ClassProbabilities`, and the caller built the pose arrays itself as fresh
        float64 arrays of shapes ``(n, 2)``, ``(n,)`` and ``(n,)`` (they are made read-only
        here). Everything a plugin constructs goes through ``__init__`` and its checks.
        """
        positions_m.setflags(write=False)
        headings_rad.setflags(write=False)
        depth_m.setflags(write=False)
        record = object.__new__(cls)
        # The fields as __init__ would leave them (a frozen dataclass keeps them in __dict__).
        record.__dict__.update(
            timestamps_s=probabilities.timestamps_s,
            positions_m=positions_m,
            headings_rad=headings_rad,
            probabilities=probabilities.probabilities,
            classes=probabilities.classes,
            depth_m=depth_m,
        )
        return record

    def select(self, rows: slice | NDArray[np.intp] | NDArray[np.bool_]) -> LocatedMeasurement:
        return LocatedMeasurement(
            self.timestamps_s[rows],
            self.positions_m[rows],
            self.headings_rad[rows],
            self.probabilities[rows],
            self.classes,
            self.depth_m[rows],
        )


@dataclass(frozen=True, init=False)
class Observations:
    """Map observations produced by a sensor model.

    Parameters
    ----------
    points_m : (m, 2) float64
        Locations in the map frame.
    targets : (m,) float64
        Occupancy targets in [0, 1] (soft labels: 1 = object, 0 = granular material only).
    weights : (m,) float64, optional
        Non-negative confidence of each target; 1 for each when not given (the attribute is
        always an array).
    """

    points_m: FloatArray
    targets: FloatArray
    weights: FloatArray

    def __init__(
        self, points_m: ArrayLike, targets: ArrayLike, weights: ArrayLike | None = None
    ) -> None:
        pts = _as_float_array(np.reshape(points_m, (-1, 2)), "points_m", ndim=2)
        m = pts.shape[0]
        tgt = _as_float_array(targets, "targets", ndim=1)
        if tgt.shape != (m,):
            raise ValueError(f"targets must have shape ({m},), got {tgt.shape}")
        w = _as_float_array(np.ones(m) if weights is None else weights, "weights", ndim=1)
        if w.shape != (m,):
            raise ValueError(f"weights must have shape ({m},), got {w.shape}")
        if not (np.isfinite(pts).all() and np.isfinite(tgt).all() and np.isfinite(w).all()):
            raise ValueError("observations contain NaN or infinity")
        if m and (tgt.min() < 0 or tgt.max() > 1):
            raise ValueError("targets must lie in [0, 1]")
        if m and w.min() < 0:
            raise ValueError("weights must be non-negative")
        object.__setattr__(self, "points_m", pts)
        object.__setattr__(self, "targets", tgt)
        object.__setattr__(self, "weights", w)

    def __len__(self) -> int:
        return int(self.targets.size)

    @classmethod
    def empty(cls) -> Observations:
        return cls(np.empty((0, 2)), np.empty(0))

    @classmethod
    def concatenate(cls, parts: Sequence[Observations]) -> Observations:
        if not parts:
            return cls.empty()
        return cls(
            np.concatenate([p.points_m for p in parts]),
            np.concatenate([p.targets for p in parts]),
            np.concatenate([p.weights for p in parts]),
        )


@dataclass(frozen=True)
class MapEstimate:
    """Occupancy at query points: probability and its standard deviation, both in [0, 1]."""

    mean: FloatArray
    std: FloatArray

    def __post_init__(self) -> None:
        mean = _as_float_array(self.mean, "mean", ndim=1)
        std = _as_float_array(self.std, "std", ndim=1)
        if mean.shape != std.shape:
            raise ValueError(f"mean {mean.shape} and std {std.shape} differ in shape")
        if not (np.all(np.isfinite(mean)) and np.all(np.isfinite(std))):
            raise ValueError("map estimate contains NaN or infinity")
        if mean.size and (mean.min() < 0 or mean.max() > 1 or std.min() < 0):
            raise ValueError("mean must lie in [0, 1] and std must be non-negative")
        object.__setattr__(self, "mean", mean)
        object.__setattr__(self, "std", std)


@dataclass(frozen=True)
class ExploratoryMovement:
    """A straight-line exploratory movement (EM) proposed by a planner.

    Parameters
    ----------
    start_m, end_m : (2,) float64
        Start and end of the path in the map frame.
    speed_m_per_s : float
        Commanded fingertip speed.
    depth_m : float or None
        Commanded depth below the free surface; None lets the robot keep its own.
    phase : str
        Planner phase that chose it (``"phase1"``, ``"phase2"``, ``"coverage"``).
    label : str
        Short human-readable description for progress lines.
    """

    start_m: FloatArray
    end_m: FloatArray
    speed_m_per_s: float = 0.05
    depth_m: float | None = None
    phase: str = ""
    label: str = ""

    def __post_init__(self) -> None:
        start = _as_float_array(self.start_m, "start_m", ndim=1)
        end = _as_float_array(self.end_m, "end_m", ndim=1)
        if start.shape != (2,) or end.shape != (2,):
            raise ValueError("start_m and end_m must have shape (2,)")
        if not (np.all(np.isfinite(start)) and np.all(np.isfinite(end))):
            raise ValueError("movement end points must be finite")
        if not self.speed_m_per_s > 0:
            raise ValueError("speed_m_per_s must be positive")
        object.__setattr__(self, "start_m", start)
        object.__setattr__(self, "end_m", end)

    @property
    def length_m(self) -> float:
        return float(np.linalg.norm(self.end_m - self.start_m))

    @property
    def heading_rad(self) -> float:
        d = self.end_m - self.start_m
        return float(np.arctan2(d[1], d[0]))


@dataclass(frozen=True)
class RobotState:
    """The fingertip's kinematic state at one instant."""

    timestamp_s: float
    position_m: FloatArray
    heading_rad: float
    depth_m: float = float("nan")
    speed_m_per_s: float = 0.0

    def __post_init__(self) -> None:
        pos = _as_float_array(self.position_m, "position_m", ndim=1)
        if pos.shape != (2,):
            raise ValueError("position_m must have shape (2,)")
        object.__setattr__(self, "position_m", pos)


@dataclass(frozen=True)
class MovementResult:
    """What happened during one exploratory movement.

    Parameters
    ----------
    index : int
        0-based number of the movement in the run.
    movement : ExploratoryMovement
    halted : bool
        True when the movement stopped before its end (interaction detected, force limit).
    halt_reason : str
        ``""``, ``"interaction"`` or a robot-specific reason such as ``"force_limit"``.
    final_state : RobotState or None
    final_class : str
        Most probable class at the last classified sample (``""`` when nothing was classified).
    max_force_n : float
        Largest force magnitude seen (NaN when no force channel exists).
    extra : mapping
        Free-form details reported by the robot.
    """

    index: int
    movement: ExploratoryMovement
    halted: bool
    halt_reason: str
    final_state: RobotState | None
    final_class: str = ""
    max_force_n: float = float("nan")
    extra: Mapping[str, Any] = field(default_factory=dict)

    @property
    def interacted(self) -> bool:
        """True when the movement ended in a non-background state."""
        return self.halt_reason == "interaction"


# --- physical truth of simulated robots (issue 14, DESIGN §2) ---------------------------------

#: Shape of each array field of :class:`PhysicalTruth`.
_TRUTH_SHAPES = {
    "position_m": (3,),
    "orientation_wxyz": (4,),
    "linear_velocity_m_per_s": (3,),
    "linear_acceleration_m_per_s2": (3,),
    "angular_velocity_rad_per_s": (3,),
    "force_n": (3,),
    "torque_nm": (3,),
}


@dataclass(frozen=True)
class PhysicalTruth:
    """A simulated robot's physical state at one instant, in the world frame (REP 103:
    x forward, z up).

    What a simulation hands to device emulators (a wrist force/torque sensor, an IMU) so that
    they can synthesise the readings a real device on the tool would give; see
    :class:`hapticframe.kinds.capabilities.PhysicalTruthSource`.

    Parameters
    ----------
    timestamp_s : float
        Simulation time of the state.
    position_m : (3,) float64
        Origin of the wrist force/torque sensor in the world frame. Each robot documents
        where its world z = 0 lies (the sandbox: the free surface of the sand).
    orientation_wxyz : (4,) float64
        Unit quaternion (w, x, y, z) of the tool frame in the world frame (world ← tool):
        it maps a vector in tool coordinates to world coordinates. Tool x is the heading
        direction, tool z points up when the tool is upright.
    linear_velocity_m_per_s : (3,) float64
        Velocity of the sensor origin in the world frame.
    linear_acceleration_m_per_s2 : (3,) float64
        Kinematic acceleration of the sensor origin in the world frame, gravity NOT
        included (an accelerometer at rest reads the opposite of gravity; that is the
        emulator's part).
    angular_velocity_rad_per_s : (3,) float64
        Angular velocity of the tool in the world frame.
    force_n : (3,) float64
        Force the environment exerts on the tool, in the world frame (a plate dragged
        through sand feels a force against its motion).
    torque_nm : (3,) float64
        Torque of that environment force about the sensor origin, in the world frame.
    end_effector_mass_kg : float
        Mass beyond the wrist sensor (what the sensor weighs and accelerates), non-negative.

    Notes
    -----
    Every array is copied into a read-only float64 array the record owns (a read-only
    float64 array is taken as it is). Every value must be finite and the quaternion of unit
    norm (to 1e-6); a malformed record raises ``ValueError`` where it is built.
    """

    timestamp_s: float
    position_m: FloatArray
    orientation_wxyz: FloatArray
    linear_velocity_m_per_s: FloatArray
    linear_acceleration_m_per_s2: FloatArray
    angular_velocity_rad_per_s: FloatArray
    force_n: FloatArray
    torque_nm: FloatArray
    end_effector_mass_kg: float

    def __post_init__(self) -> None:
        timestamp = float(self.timestamp_s)
        if not math.isfinite(timestamp):
            raise ValueError("timestamp_s must be finite")
        object.__setattr__(self, "timestamp_s", timestamp)
        for name, shape in _TRUTH_SHAPES.items():
            array = _as_float_array(getattr(self, name), name)
            if array.shape != shape:
                raise ValueError(f"{name} must have shape {shape}, got {array.shape}")
            # A finite sum means every entry is finite (NaN and infinities propagate).
            if not math.isfinite(sum(array.tolist())):
                raise ValueError(f"{name} contains NaN or infinity")
            object.__setattr__(self, name, array)
        norm = math.sqrt(sum(v * v for v in self.orientation_wxyz.tolist()))
        if abs(norm - 1.0) > 1e-6:
            raise ValueError(f"orientation_wxyz must be a unit quaternion, got norm {norm:.9g}")
        mass = float(self.end_effector_mass_kg)
        if not (math.isfinite(mass) and mass >= 0):
            raise ValueError(f"end_effector_mass_kg must be non-negative and finite, got {mass}")
        object.__setattr__(self, "end_effector_mass_kg", mass)

    @property
    def rotation_matrix(self) -> FloatArray:
        """The (3, 3) rotation matrix of :attr:`orientation_wxyz` (world ← tool)."""
        return rotation_matrix_from_wxyz(self.orientation_wxyz)
