"""The SPI-batch backend interface and an emulated BioTac behind it.

A real BioTac is read through a Total Phase Cheetah USB-SPI adapter, whose proprietary
``cheetah.so`` (and its ``cheetah_py`` wrapper) is not on PyPI for Linux and cannot be
installed here. Everything above the adapter (schedule, parity, decoding) is pure Python in
:mod:`._wire`, so the adapter is reduced to :class:`SpiBatchBackend`: clock ``n`` words of the
frame schedule out of the sensor and say when the transfer finished. A Cheetah backend
implements it by queueing, per word, "CS all → sampling command from
:attr:`FrameSchedule.commands` → CS none → 50 µs → CS sensor → clock 2 bytes" as one async
batch, collecting it, and returning the sensor's bytes with the host's completion time.

:class:`EmulatedBioTac` implements the same interface in software, like httpx's
``MockTransport``: it is both the sensor's ``spi`` source without hardware and the decoder's
test fixture. Faults (parity errors, stale words, dropped frames) are injected at given
positions or at given rates from a seeded ``numpy.random.Generator``, and every injected fault
is logged so tests can compare the decoder's verdicts with the truth.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Iterable
from dataclasses import dataclass, field
from typing import Literal

import numpy as np
from numpy.typing import NDArray

from ._frame import COUNT_MAX, SLOT_RATE_HZ, BioTacFrames, layout_for
from ._wire import ERROR_PREFIX, encode_values, frame_values, schedule_for

__all__ = [
    "EmulatedBioTac",
    "FaultPlan",
    "InjectedFault",
    "SpiBatchBackend",
    "plan_from_positions",
    "resting_frame_values",
]


class SpiBatchBackend(ABC):
    """What the decoder needs from an SPI adapter: words of the frame schedule, with host time.

    Implementations must start at slot 0 of :func:`schedule_for` ``(variant)`` and keep the
    schedule's order across calls; they may lose whole frames (the host fell behind), never
    part of one.
    """

    variant: str

    @abstractmethod
    def read_words(self, n: int) -> bytes:
        """Clock the next ``n`` words (2 bytes each, MSB first). Fewer only when exhausted."""

    @property
    @abstractmethod
    def transfer_end_time_s(self) -> float:
        """Host time (seconds) at which the last :meth:`read_words` transfer completed."""

    @property
    def exhausted(self) -> bool:
        """True when a finite source has no more words. Hardware: never."""
        return False

    def close(self) -> None:
        """Release the adapter. Default: nothing."""


@dataclass(frozen=True)
class InjectedFault:
    """One fault the emulator injected: sensor frame number, word slot, kind and byte (parity)."""

    frame: int
    slot: int
    kind: Literal["parity", "stale", "dropped"]
    byte: int = -1


@dataclass(frozen=True)
class FaultPlan:
    """Faults to inject, at fixed positions and/or at random with the given rates.

    Parameters
    ----------
    parity_error_rate, stale_word_rate : float
        Probability per word of a flipped bit (parity error) or a stale "E-" answer.
    dropped_frame_rate : float
        Probability per frame that the host misses it. Frame 0 is never dropped (nothing
        before it could reveal the gap).
    parity_errors : iterable of (frame, slot, byte)
    stale_words : iterable of (frame, slot)
    dropped_frames : iterable of frame numbers
    """

    parity_error_rate: float = 0.0
    stale_word_rate: float = 0.0
    dropped_frame_rate: float = 0.0
    parity_errors: frozenset[tuple[int, int, int]] = field(default_factory=frozenset)
    stale_words: frozenset[tuple[int, int]] = field(default_factory=frozenset)
    dropped_frames: frozenset[int] = field(default_factory=frozenset)

    def __post_init__(self) -> None:
        for name in ("parity_error_rate", "stale_word_rate", "dropped_frame_rate"):
            rate = getattr(self, name)
            if not 0.0 <= rate <= 1.0:
                raise ValueError(f"{name} must lie in [0, 1], got {rate}")
        object.__setattr__(self, "parity_errors", frozenset(tuple(p) for p in self.parity_errors))
        object.__setattr__(self, "stale_words", frozenset(tuple(s) for s in self.stale_words))
        object.__setattr__(self, "dropped_frames", frozenset(int(f) for f in self.dropped_frames))
        if any(b not in (0, 1) for _, _, b in self.parity_errors):
            raise ValueError("a parity error names byte 0 or 1 of a word")


def resting_frame_values(variant: str, n: int, rng: np.random.Generator,
                         state: dict[str, NDArray[np.float64]] | None = None) -> NDArray[np.int64]:
    """(n, F) slot values of a fingertip at rest in air, continuing from ``state``.

    Electrodes sit in the rest band (2,600–3,400 counts, one baseline per electrode, σ 3
    counts of noise), pdc and tdc drift slowly, tac and pac are noise about mid-scale.
    ``state`` (updated in place) carries the baselines and drifts between calls.
    """
    layout = layout_for(variant)
    if state is None:
        state = {}
    if "electrodes" not in state:
        state["electrodes"] = rng.uniform(2600.0, 3400.0, layout.n_electrodes)
        state["pdc"] = np.array([rng.uniform(1800.0, 2000.0)])
        state["tdc"] = np.array([rng.uniform(2500.0, 2700.0)])
    pdc = state["pdc"][0] + np.cumsum(rng.normal(0.0, 0.2, n))
    tdc = state["tdc"][0] + np.cumsum(rng.normal(0.0, 0.05, n))
    if n:
        state["pdc"][0], state["tdc"][0] = pdc[-1], tdc[-1]
    frames = BioTacFrames(
        layout,
        np.arange(n, dtype=np.float64),
        2048.0 + rng.normal(0.0, 4.0, (n, layout.n_pac)),
        pdc,
        2048.0 + rng.normal(0.0, 2.0, n),
        tdc,
        state["electrodes"] + rng.normal(0.0, 3.0, (n, layout.n_electrodes)),
    )
    rounded = {name: np.clip(np.round(getattr(frames, name)), 0, COUNT_MAX)
               for name in ("pac", "pdc", "tac", "tdc", "electrodes")}
    return frame_values(BioTacFrames(layout, frames.timestamps_s, **rounded))


class EmulatedBioTac(SpiBatchBackend):
    """A BioTac and its adapter in software, with injectable faults.

    Parameters
    ----------
    variant : {"biotac", "biotac_sp"}
    rng : numpy.random.Generator
        Draws the resting signal, random faults and transfer jitter.
    content : BioTacFrames, optional
        Frames to clock out instead of the resting signal (a recording, a synthetic trial);
        they must hold 12-bit integer counts. The source ends after them.
    max_frames : int, optional
        End after this many sensor frames (dropped ones included). None: endless (rest only).
    faults : FaultPlan, optional
    jitter_s : float
        Each transfer's reported completion time is late by U(0, jitter_s); keep it below half
        a frame period or drops cannot be told from jitter.
    t0_s : float
        Host time at which sampling starts.
    """

    _CHUNK = 64

    def __init__(
        self,
        variant: str = "biotac",
        rng: np.random.Generator | None = None,
        *,
        content: BioTacFrames | None = None,
        max_frames: int | None = None,
        faults: FaultPlan | None = None,
        jitter_s: float = 0.0,
        t0_s: float = 0.0,
    ) -> None:
        self.variant = variant
        self.schedule = schedule_for(variant)
        self.rng = rng if rng is not None else np.random.default_rng(0)
        self.faults = faults or FaultPlan()
        if content is not None and content.layout.variant != variant:
            raise ValueError(f"content frames are {content.layout.variant}, emulator is {variant}")
        self._content = None if content is None else frame_values(content)
        limit = None if content is None else len(content)
        if max_frames is not None:
            if max_frames < 0:
                raise ValueError(f"max_frames must be non-negative, got {max_frames}")
            limit = max_frames if limit is None else min(limit, max_frames)
        self.max_frames = limit
        if not 0.0 <= jitter_s < 0.5 * layout_for(variant).frame_period_s:
            raise ValueError(f"jitter_s must lie in [0, half a frame period), got {jitter_s}")
        self.jitter_s = float(jitter_s)
        self.t0_s = float(t0_s)
        self.injected: list[InjectedFault] = []
        self._rest_state: dict[str, NDArray[np.float64]] = {}
        self._cache_start = 0
        self._cache = np.empty((0, self.schedule.frame_words), dtype=np.int64)
        self._frame = 0          # sensor frame being clocked (dropped frames included)
        self._slot = 0           # next slot within it
        self._frame_bytes: bytes = b""
        self._end_time = self.t0_s

    # -- SpiBatchBackend --------------------------------------------------------------------

    @property
    def transfer_end_time_s(self) -> float:
        return self._end_time

    @property
    def exhausted(self) -> bool:
        return self.max_frames is not None and self._frame >= self.max_frames

    def read_words(self, n: int) -> bytes:
        if n < 0:
            raise ValueError(f"cannot read {n} words")
        out = bytearray()
        F = self.schedule.frame_words
        while len(out) < 2 * n:
            if self._slot == 0:
                self._skip_dropped()
                if self.exhausted:
                    break
                self._frame_bytes = self._frame_words(self._frame)
            take = min(F - self._slot, n - len(out) // 2)
            out += self._frame_bytes[2 * self._slot: 2 * (self._slot + take)]
            self._slot += take
            if self._slot == F:
                self._slot = 0
                self._frame += 1
        words_done = self._frame * F + self._slot
        self._end_time = self.t0_s + words_done / SLOT_RATE_HZ + (
            self.rng.uniform(0.0, self.jitter_s) if self.jitter_s else 0.0
        )
        return bytes(out)

    # -- internals --------------------------------------------------------------------------

    def _skip_dropped(self) -> None:
        while not self.exhausted and self._frame > 0:
            drop = self._frame in self.faults.dropped_frames
            if self.faults.dropped_frame_rate:
                drop |= bool(self.rng.random() < self.faults.dropped_frame_rate)
            if not drop:
                return
            self.injected.append(InjectedFault(self._frame, -1, "dropped"))
            self._frame += 1

    def _values(self, frame: int) -> NDArray[np.int64]:
        if self._content is not None:
            return self._content[frame]
        while frame >= self._cache_start + len(self._cache):
            self._cache_start += len(self._cache)
            self._cache = resting_frame_values(
                self.variant, self._CHUNK, self.rng, self._rest_state
            )
        return self._cache[frame - self._cache_start]

    def _frame_words(self, frame: int) -> bytes:
        data = encode_values(self._values(frame)).reshape(-1, 2)
        F = self.schedule.frame_words
        stale = {s for f, s in self.faults.stale_words if f == frame}
        parity = {(s, b) for f, s, b in self.faults.parity_errors if f == frame}
        if self.faults.stale_word_rate:
            stale |= set(np.flatnonzero(self.rng.random(F) < self.faults.stale_word_rate).tolist())
        if self.faults.parity_error_rate:
            hits = np.flatnonzero(self.rng.random(F) < self.faults.parity_error_rate)
            parity |= {(int(s), int(self.rng.integers(2))) for s in hits}
        for slot in sorted(stale):
            data[slot] = (ERROR_PREFIX, 0x2D)  # "E-": insufficient sampling delay
            self.injected.append(InjectedFault(frame, slot, "stale"))
        for slot, byte in sorted(parity):
            if slot in stale:
                continue  # the word is already an error word
            # Any one flipped bit breaks odd parity.
            data[slot, byte] ^= np.uint8(1 << int(self.rng.integers(8)))
            self.injected.append(InjectedFault(frame, slot, "parity", byte))
        return data.tobytes()

    def faults_of(self, kind: str) -> list[InjectedFault]:
        """The injected faults of one kind, in order."""
        return [f for f in self.injected if f.kind == kind]


def plan_from_positions(
    parity: Iterable[tuple[int, int, int]] = (),
    stale: Iterable[tuple[int, int]] = (),
    dropped: Iterable[int] = (),
) -> FaultPlan:
    """A :class:`FaultPlan` with faults at fixed positions only."""
    return FaultPlan(
        parity_errors=frozenset(parity),
        stale_words=frozenset(stale),
        dropped_frames=frozenset(dropped),
    )
