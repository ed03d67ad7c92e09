"""Real BioTac recordings in the Penn haptics "BOLT" HDF5 layout (a PR2 gripper, two BioTacs).

Layout (one file per object, read with h5py, the ``hdf5`` extra)::

    <trial>/timestamps            (n,) int, whole seconds since 1970
    <trial>/finger_0/pac          (n, 22) raw 12-bit counts
    <trial>/finger_0/pdc, tac, tdc (n,)
    <trial>/finger_0/electrodes   (n, 19)
    <trial>/finger_1/...          the other fingertip, same frames

Every trial of a file and both fingers are read, as raw counts (the layout holds no
contact labels). The stamps are whole seconds only, so the frame clock is rebuilt
(:func:`rebuild_frame_clock`): frames are 10 ms apart (the BioTac's 100 Hz frame rate), and
the clock's phase within the first second is the one that puts the most frames in the
second they are stamped with. The recording's metadata says so (``clock``) and counts the
frames whose rebuilt second differs from their stamp (``clock_mismatched_frames``: the
BioTac's frame clock is not locked to the host's, so a second holds 99 or 101 frames now
and then).

The data of the public BOLT repository carry no stated licence: read them from a path, never
copy them into a repository (tests write small files in the same layout).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from hapticframe.bounded_io import (
    MAX_RECORDING_BYTES,
    BoundedReadError,
    hdf5_child,
    hdf5_members,
    open_hdf5,
    read_hdf5_dataset,
)

from ._frame import BioTacFrames, layout_for
from ._replay import Recording, ReplayFormatError

__all__ = [
    "BOLT_FRAME_RATE_HZ",
    "BoltTrial",
    "load_bolt",
    "load_bolt_dir",
    "rebuild_frame_clock",
    "save_bolt",
]

#: The BioTac's frame rate, which the rebuilt clock assumes.
BOLT_FRAME_RATE_HZ = 100.0
#: Values one BOLT file may hold in all its datasets (each is read once and converted to
#: float64: 16 bytes a value at the peak, :data:`MAX_RECORDING_BYTES` in all).
MAX_BOLT_CELLS = MAX_RECORDING_BYTES // 16
FINGERS = ("finger_0", "finger_1")
_CHANNELS = {"pac": 2, "pdc": 1, "tac": 1, "tdc": 1, "electrodes": 2}


@dataclass(frozen=True)
class BoltTrial:
    """One fingertip of one BOLT trial: ``object`` (the file's stem), ``trial`` (its group)
    and ``finger`` (0 or 1), with the frames and metadata as any other recording."""

    object: str
    trial: str
    finger: int
    recording: Recording

    @property
    def frames(self) -> BioTacFrames:
        return self.recording.frames


def rebuild_frame_clock(
    stamps_s: NDArray[Any], rate_hz: float = BOLT_FRAME_RATE_HZ
) -> tuple[NDArray[np.float64], float, int]:
    """A frame clock at ``rate_hz`` for frames stamped with whole seconds only.

    Frame k is at ``start + k / rate_hz``. ``start`` lies in ``[stamps[0], stamps[0] + 1)``
    and is chosen to maximise the frames whose rebuilt time falls in the second they are
    stamped with (ties: the earliest such phase).

    Returns
    -------
    times_s : (n,) float64
        Seconds since the first frame (0, 0.01, ...).
    start_s : float
        The rebuilt time of the first frame, in the stamps' clock.
    mismatched : int
        Frames whose rebuilt second differs from their stamp.
    """
    stamps = np.asarray(stamps_s, dtype=np.float64)
    n = stamps.size
    offsets = np.arange(n, dtype=np.float64) / rate_hz
    if n == 0:
        return offsets, 0.0, 0
    # Frame k matches for phases in [stamp_k - stamp_0 - k/rate, ... + 1); sweep the
    # phase in [0, 1) over every interval's start (a difference array on a 1/rate grid).
    grid = max(1, round(rate_hz))
    low = stamps - stamps[0] - offsets
    hits = np.zeros(2 * grid + 2, dtype=np.int64)
    # Phases are multiples of 1/grid: exact for frames 1/rate apart when rate is whole.
    start_bin = np.ceil(np.round(low * grid, 6)).astype(np.int64)
    lo = np.clip(start_bin, 0, grid)
    hi = np.clip(start_bin + grid, 0, grid)
    np.add.at(hits, lo, 1)
    np.add.at(hits, hi, -1)
    counts = np.cumsum(hits)[:grid]
    phase = int(np.argmax(counts)) / grid
    start = float(stamps[0]) + phase
    rebuilt_second = np.floor(np.round(start + offsets - stamps[0], 9)) + stamps[0]
    mismatched = int(np.count_nonzero(rebuilt_second != stamps))
    return offsets, start, mismatched


def _dataset(path: Path, group: Any, name: str, ndim: int, n: int | None,
             budget: list[int]) -> NDArray[np.float64]:
    import h5py

    where = f"{group.name}/{name}"
    try:
        item = hdf5_child(group, name)
        if not isinstance(item, h5py.Dataset):
            raise ReplayFormatError(path, f"{where}: missing (a BOLT trial holds timestamps "
                                    "and finger_0/finger_1 with pac, pdc, tac, tdc and "
                                    "electrodes)")
        raw = read_hdf5_dataset(item, budget[0], kinds="iuf")
    except BoundedReadError as exc:
        raise ReplayFormatError(path, str(exc)) from None
    budget[0] -= raw.size
    values = np.asarray(raw, dtype=np.float64)
    if values.ndim != ndim or (n is not None and values.shape[0] != n):
        want = f"{n if n is not None else 'n'} rows, {ndim}-D"
        raise ReplayFormatError(path, f"{where}: shape {values.shape}, expected {want}")
    bad = ~np.isfinite(values)
    if bad.any():
        row = int(np.argwhere(bad)[0][0])
        raise ReplayFormatError(path, f"{where}: row {row} is not finite")
    return values


def _trial(path: Path, name: str, group: Any, budget: list[int]) -> list[BoltTrial]:
    import h5py

    stamps = _dataset(path, group, "timestamps", 1, None, budget)
    n = stamps.size
    if n == 0:
        raise ReplayFormatError(path, f"{group.name}/timestamps: the trial holds no frames")
    if np.any(np.diff(stamps) < 0):
        row = int(np.flatnonzero(np.diff(stamps) < 0)[0]) + 1
        raise ReplayFormatError(path, f"{group.name}/timestamps: row {row} goes back in time")
    times, start, mismatched = rebuild_frame_clock(stamps)
    layout = layout_for("biotac")
    out = []
    for finger, finger_name in enumerate(FINGERS):
        try:
            finger_group = hdf5_child(group, finger_name)
        except BoundedReadError as exc:
            raise ReplayFormatError(path, str(exc)) from None
        if not isinstance(finger_group, h5py.Group):
            raise ReplayFormatError(path, f"{group.name}/{finger_name}: missing (BOLT trials "
                                    "hold finger_0 and finger_1)")
        channels = {c: _dataset(path, finger_group, c, d, n, budget)
                    for c, d in _CHANNELS.items()}
        try:
            frames = BioTacFrames.from_channels(layout, times, channels)
        except ValueError as exc:
            raise ReplayFormatError(path, f"{group.name}/{finger_name}: {exc}") from None
        meta = {
            "format": "penn-bolt-hdf5", "variant": "biotac", "object": path.stem,
            "trial": name, "finger": finger, "n_frames": n, "source": str(path),
            "clock": f"rebuilt: frames {1000 / BOLT_FRAME_RATE_HZ:g} ms apart (the BioTac's "
            f"{BOLT_FRAME_RATE_HZ:g} Hz frame rate); the file stamps whole seconds only",
            "frame_rate_hz": BOLT_FRAME_RATE_HZ, "start_time_s": start,
            "clock_mismatched_frames": mismatched, "counts": "raw 12-bit",
        }
        out.append(BoltTrial(path.stem, name, finger, Recording(frames, meta)))
    return out


def load_bolt(path: str | Path, trials: Sequence[str] | None = None) -> list[BoltTrial]:
    """Every trial (or the named ``trials``) of one BOLT file, both fingers, in file order.

    Raises
    ------
    ReplayFormatError
        The file is missing or not HDF5, a trial lacks a dataset, a dataset has the wrong
        shape or a value that is not finite, or a named trial is not in the file (each
        located by file and dataset path).
    """
    try:
        import h5py
    except ImportError as exc:  # pragma: no cover - the extra is missing
        raise ReplayFormatError(path, "reading BOLT HDF5 files needs h5py: pip install "
                                "'hapticframe[hdf5]'") from exc
    path = Path(path)
    try:
        handle = open_hdf5(path)
    except FileNotFoundError:
        raise ReplayFormatError(path, "no such file") from None
    except BoundedReadError as exc:
        raise ReplayFormatError(path, str(exc)) from None
    with handle:
        try:
            names = [k for k, node in hdf5_members(handle) if isinstance(node, h5py.Group)]
        except BoundedReadError as exc:
            raise ReplayFormatError(path, str(exc)) from None
        if trials is not None:
            unknown = [t for t in trials if t not in names]
            if unknown:
                raise ReplayFormatError(path, f"no trial {unknown[0]!r}; it holds "
                                        f"{', '.join(names) or 'none'}")
            names = [t for t in names if t in set(trials)]
        if not names:
            raise ReplayFormatError(path, "holds no trial groups (not a BOLT file)")
        budget = [MAX_BOLT_CELLS]  # values every dataset of the file may hold in all
        return [t for name in names
                for t in _trial(path, name, hdf5_child(handle, name), budget)]


def load_bolt_dir(directory: str | Path) -> list[BoltTrial]:
    """Every ``*.h5`` file of ``directory`` (sorted by name) through :func:`load_bolt`."""
    directory = Path(directory)
    if not directory.is_dir():
        raise ReplayFormatError(directory, "not a directory of BOLT .h5 files")
    files = sorted(directory.glob("*.h5"))
    if not files:
        raise ReplayFormatError(directory, "holds no .h5 files")
    return [t for f in files for t in load_bolt(f)]


def save_bolt(
    path: str | Path, trials: Mapping[str, tuple[ArrayLike, Sequence[Mapping[str, ArrayLike]]]]
) -> Path:
    """Write trials in the BOLT layout (for tests and examples: the real files stay outside).

    ``trials`` maps a trial's name to its whole-second stamps and the two fingers' channels
    (``pac``, ``pdc``, ``tac``, ``tdc``, ``electrodes``), stored as int64 as in BOLT.
    """
    import h5py

    path = Path(path)
    with h5py.File(path, "w") as handle:
        for name, (stamps, fingers) in trials.items():
            group = handle.create_group(name)
            group.create_dataset("timestamps", data=np.asarray(stamps, dtype=np.int64))
            for finger_name, channels in zip(FINGERS, fingers, strict=True):
                sub = group.create_group(finger_name)
                for channel in _CHANNELS:
                    sub.create_dataset(channel, data=np.asarray(channels[channel],
                                                                dtype=np.int64))
    return path
