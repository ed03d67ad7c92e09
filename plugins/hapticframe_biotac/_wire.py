"""The BioTac SPI word stream: frame schedule, parity, an incremental decoder and its encoder.

Pure numpy; no I/O. Sources: SynTouch's C driver as packaged in
``kth-ros-pkg/biotac_driver`` (``biotac.h``, ``biotac.c``, ``biotac_hand_class.cpp``) and the
BioTac SP node ``CNCR-NTU/biotac_sp_ros`` (``biotac.h``), summarised in the project's
``notes/hardware.md`` §5. This module is written from that description, not from their code.

Wire format
-----------
*Sampling command* (host → sensor, one byte per slot): bit 7 set, bits 6..1 the channel
index (pac 0, pdc 1, tac 2, tdc 3, electrode k at 16 + k), bit 0 making the byte's parity
odd, e.g. pac ``0x80``, pdc ``0x83``, E01 ``0xA2``, E19 ``0xC7``, E24 ``0xD0``.

*Word* (sensor → host, two bytes per slot, MSB first): the 12-bit value's upper 7 bits in
bits 7..1 of byte 0 and its lower 5 bits in bits 7..3 of byte 1; bit 0 of **each** byte is an
odd-parity bit over that byte. Bits 2..1 of byte 1 carry nothing and are not checked.

*Frame schedule*: every slow channel is followed by one pac word, so pac is sampled at half
the word rate (2200 Hz at the default 4400 words/s)::

    BioTac    (44 words, 10 ms):   E01 PAC E02 PAC … E19 PAC PDC PAC TAC PAC TDC PAC
    BioTac SP (54 words, 12.3 ms): E01 PAC E02 PAC … E24 PAC PDC PAC TAC PAC TDC PAC

i.e. 22 pac samples per BioTac frame and 27 per SP frame.

*Sensor error words*: byte 0 ``0xA5`` followed by an ASCII code ("E-" insufficient sampling
delay, "E." insufficient delay, "E_" nothing to resend, "EE" parity, "E?" unknown command,
"EX" channel not recognised, "ER" read-only, "EW" write error). ``0xA5`` has even parity, so
no data word can begin with it and the two cannot be confused.

Decoder rules (what this module does differently from the reference driver)
---------------------------------------------------------------------------
The reference ROS driver skips a word whose parity fails and leaves the previous value in
its field, so the output silently repeats a stale value; worse, its per-finger index only
advances on good parity, so one bad word from one sensor lands the next sensor's value in its
slot. Here every word's position is fixed by the schedule (word ``i`` of a frame is always
slot ``i``), and a bad word is marked invalid **for its own channel only**; no other word
moves. Specifically:

- *Parity error* (either byte with even parity): the word is invalid; the value delivered is
  held from the channel's last valid sample (pac: the previous pac sample in time) and
  flagged in ``word_valid``.
- *Stale word*: the sensor answering a slot with "E-", "E." or "E_" has no fresh
  conversion for it. That is the only in-band staleness signal the protocol has (there is no
  sample counter on the wire), so those error words are counted as stale, held and flagged
  like parity errors. Other error words are counted as sensor errors and treated the same.
- *Dropped frames*: the protocol has no frame counter either, so drops are found from host
  time. Each frame's time is the transfer's completion time less the words clocked after it
  (at 4400 words/s); when the time since the previous frame rounds to ``m > 1`` frame
  periods, ``m - 1`` frames were lost. The frame counter skips them, and with
  ``on_dropped="mark"`` they are delivered as rows holding the last values, every word
  invalid (so downstream ring buffers keep a regular 100 Hz grid); with ``"skip"`` they are
  only counted. The Cheetah adapter collects whole batches of whole frames, so a drop never
  tears a frame; the decoder relies on that (a transfer is assumed to start at slot 0 of the
  schedule, and a partial frame is completed by the next transfer).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ._frame import (
    SIGNAL_CHANNELS,
    SLOT_RATE_HZ,
    BioTacFrames,
    FrameLayout,
    check_counts,
    layout_for,
)

__all__ = [
    "ERROR_PREFIX",
    "STALE_CODES",
    "DecoderStats",
    "FrameSchedule",
    "WordStreamDecoder",
    "command_byte",
    "decode_words",
    "encode_frames",
    "encode_values",
    "frame_values",
    "has_odd_parity",
    "schedule_for",
]

#: First byte of a sensor error word ("\xA5" then an ASCII code).
ERROR_PREFIX = 0xA5
#: Error codes that mean "no fresh sample for this slot": '-', '.', '_'.
STALE_CODES = frozenset({0x2D, 0x2E, 0x5F})
_POPCOUNT = np.array([bin(b).count("1") for b in range(256)], dtype=np.uint8)
_CHANNEL_INDEX = {"pac": 0, "pdc": 1, "tac": 2, "tdc": 3}
_ELECTRODE_BASE = 16


def has_odd_parity(data: ArrayLike) -> NDArray[np.bool_]:
    """Per byte: True when the number of set bits is odd."""
    return (_POPCOUNT[np.asarray(data, dtype=np.uint8)] & 1).astype(bool)


def command_byte(channel_index: int) -> int:
    """The sampling command for channel index 0..63, with its odd-parity bit."""
    if not 0 <= channel_index < 64:
        raise ValueError(f"channel index {channel_index} does not fit in 6 bits")
    byte = 0x80 | (channel_index << 1)
    return byte | (0 if _POPCOUNT[byte] & 1 else 1)


@dataclass(frozen=True)
class FrameSchedule:
    """Which channel each word slot of a frame samples.

    Attributes
    ----------
    layout : FrameLayout
    channel : (F,) int
        Index into :data:`SIGNAL_CHANNELS` (0 pac, 1 pdc, 2 tac, 3 tdc, 4 electrodes).
    element : (F,) int
        pac sample number, electrode number − 1, or 0 for the scalar channels.
    commands : bytes
        The F sampling commands the host sends.
    """

    layout: FrameLayout
    channel: NDArray[np.intp]
    element: NDArray[np.intp]
    commands: bytes

    @property
    def frame_words(self) -> int:
        return int(self.channel.size)

    def slots_of(self, channel: str) -> NDArray[np.intp]:
        """Slot numbers of ``channel``'s words, in element order."""
        code = SIGNAL_CHANNELS.index(channel)
        slots = np.flatnonzero(self.channel == code)
        return slots[np.argsort(self.element[slots], kind="stable")]


def schedule_for(variant: str) -> FrameSchedule:
    """The firmware's default frame schedule for ``variant`` (44 or 54 words)."""
    layout = layout_for(variant)
    slow: list[tuple[int, int, int]] = [  # (channel code, element, channel index on the wire)
        (4, k, _ELECTRODE_BASE + 1 + k) for k in range(layout.n_electrodes)
    ]
    slow += [
        (1, 0, _CHANNEL_INDEX["pdc"]),
        (2, 0, _CHANNEL_INDEX["tac"]),
        (3, 0, _CHANNEL_INDEX["tdc"]),
    ]
    channel, element, commands = [], [], []
    for pac_number, (code, elem, wire_index) in enumerate(slow):
        channel += [code, 0]
        element += [elem, pac_number]
        commands += [command_byte(wire_index), command_byte(_CHANNEL_INDEX["pac"])]
    schedule = FrameSchedule(
        layout, np.array(channel, dtype=np.intp), np.array(element, dtype=np.intp), bytes(commands)
    )
    if schedule.frame_words != layout.frame_words or len(schedule.slots_of("pac")) != layout.n_pac:
        raise AssertionError("frame schedule disagrees with the layout")  # guards the tables above
    return schedule


def encode_values(values: ArrayLike) -> NDArray[np.uint8]:
    """12-bit counts → wire bytes (two per value, each with its odd-parity bit)."""
    v = check_counts(values, "word values").ravel()
    hi = ((v >> 5) & 0x7F).astype(np.uint8) << 1
    lo = (v & 0x1F).astype(np.uint8) << 3
    hi |= (~has_odd_parity(hi)).astype(np.uint8)
    lo |= (~has_odd_parity(lo)).astype(np.uint8)
    return np.stack([hi, lo], axis=-1).ravel()


def decode_words(data: ArrayLike) -> tuple[NDArray[np.int64], NDArray[np.bool_], NDArray[np.uint8]]:
    """Wire bytes → (values, parity_ok, error_code) per word.

    ``error_code`` is the second byte of a sensor error word (``0xA5 xx``) and 0 elsewhere.
    A trailing odd byte is an error.
    """
    raw = (
        np.frombuffer(bytes(data), dtype=np.uint8)
        if isinstance(data, (bytes, bytearray))
        else np.asarray(data, dtype=np.uint8)
    )
    if raw.size % 2:
        raise ValueError(f"{raw.size} bytes do not make whole 16-bit words")
    pairs = raw.reshape(-1, 2)
    b0 = pairs[:, 0].astype(np.int64)
    b1 = pairs[:, 1].astype(np.int64)
    values = ((b0 >> 1) << 5) | (b1 >> 3)
    parity_ok = has_odd_parity(pairs[:, 0]) & has_odd_parity(pairs[:, 1])
    error_code = np.where(b0 == ERROR_PREFIX, pairs[:, 1], 0).astype(np.uint8)
    return values, parity_ok, error_code


def frame_values(frames: BioTacFrames) -> NDArray[np.int64]:
    """(n, F) counts in slot order: what the sensor clocks out for each frame."""
    schedule = schedule_for(frames.layout.variant)
    out = np.empty((len(frames), schedule.frame_words), dtype=np.int64)
    for name in SIGNAL_CHANNELS:
        counts = check_counts(getattr(frames, name), name).reshape(len(frames), -1)
        out[:, schedule.slots_of(name)] = counts
    return out


def encode_frames(frames: BioTacFrames) -> bytes:
    """The word stream of ``frames`` (the inverse of :class:`WordStreamDecoder`)."""
    return encode_values(frame_values(frames)).tobytes()


@dataclass
class DecoderStats:
    """Counters kept by the decoder (health telemetry)."""

    words: int = 0
    frames: int = 0
    parity_errors: int = 0
    stale_words: int = 0
    sensor_errors: int = 0
    dropped_frames: int = 0
    filled_frames: int = 0


class WordStreamDecoder:
    """Incremental decoder: wire bytes in, :class:`BioTacFrames` out (see the module notes).

    Parameters
    ----------
    variant : {"biotac", "biotac_sp"}
    on_dropped : {"mark", "skip"}
        Deliver dropped frames as invalid rows holding the last values, or leave them out.
    max_fill_frames : int
        At most this many rows are filled for one gap (a sensor unplugged for an hour must
        not produce 360 000 rows); the rest of the gap is skipped but counted.
    """

    def __init__(
        self,
        variant: str = "biotac",
        *,
        on_dropped: Literal["mark", "skip"] = "mark",
        max_fill_frames: int = 1000,
    ) -> None:
        if on_dropped not in ("mark", "skip"):
            raise ValueError(f"on_dropped must be 'mark' or 'skip', got {on_dropped!r}")
        self.schedule = schedule_for(variant)
        self.layout = self.schedule.layout
        self.on_dropped = on_dropped
        self.max_fill_frames = int(max_fill_frames)
        self._pac_slots = self.schedule.slots_of("pac")
        self.reset()

    def reset(self) -> None:
        """Forget buffered bytes, held values, the frame counter and the statistics."""
        self._pending = b""
        self._held = {name: np.zeros(self.layout.shape_of(name)) for name in SIGNAL_CHANNELS}
        self._held_pac_last = 0.0
        self._next_index = 0
        self._last_time: float | None = None
        self.stats = DecoderStats()

    @property
    def slot_period_s(self) -> float:
        return 1.0 / SLOT_RATE_HZ

    def feed(self, data: bytes, t_end_s: float) -> BioTacFrames:
        """Decode ``data``, whose last byte arrived at host time ``t_end_s``.

        Returns the frames completed by this transfer (possibly none), including filled
        rows for dropped frames when ``on_dropped="mark"``.
        """
        if not np.isfinite(t_end_s):
            raise ValueError(f"transfer time must be finite, got {t_end_s}")
        buffer = self._pending + bytes(data)
        frame_bytes = 2 * self.schedule.frame_words
        k = len(buffer) // frame_bytes
        self._pending = buffer[k * frame_bytes:]
        if k == 0:
            return BioTacFrames.empty(self.layout)
        words_after_last = (len(self._pending)) // 2
        values, parity_ok, error_code = decode_words(buffer[: k * frame_bytes])
        F = self.schedule.frame_words
        values = values.reshape(k, F).astype(np.float64)
        is_error = (error_code != 0).reshape(k, F)
        is_stale = np.isin(error_code, list(STALE_CODES)).reshape(k, F) & is_error
        valid = parity_ok.reshape(k, F) & ~is_error
        self.stats.words += k * F
        self.stats.stale_words += int(is_stale.sum())
        self.stats.sensor_errors += int((is_error & ~is_stale).sum())
        self.stats.parity_errors += int((~parity_ok.reshape(k, F) & ~is_error).sum())
        times = t_end_s - self.slot_period_s * (words_after_last + F * np.arange(k - 1, -1, -1))
        parts = []
        for i in range(k):
            parts.extend(self._one_frame(values[i], valid[i], float(times[i])))
        return BioTacFrames.concatenate(parts)

    # -- per frame ------------------------------------------------------------------------

    def _one_frame(
        self, values: NDArray[np.float64], valid: NDArray[np.bool_], t: float
    ) -> list[BioTacFrames]:
        out: list[BioTacFrames] = []
        period = self.layout.frame_period_s
        if self._last_time is not None:
            if t <= self._last_time:  # host clock went back: keep order, say nothing is lost
                t = float(np.nextafter(self._last_time, np.inf))
            elapsed = int(np.floor((t - self._last_time) / period + 0.5))
            missing = max(elapsed - 1, 0)
            if missing:
                self.stats.dropped_frames += missing
                if self.on_dropped == "mark":
                    fill = min(missing, self.max_fill_frames)
                    out.append(self._filled(fill, self._last_time, period))
                self._next_index += missing
        channels, masks = {}, {}
        for name in SIGNAL_CHANNELS:
            slots = self._pac_slots if name == "pac" else self.schedule.slots_of(name)
            v, ok = values[slots], valid[slots]
            if name == "pac":
                v = self._hold_pac(v, ok)
            else:
                held = self._held[name].reshape(-1)
                v = np.where(ok, v, held)
                self._held[name] = v.reshape(self.layout.shape_of(name)).copy()
            shape = self.layout.shape_of(name)
            channels[name] = v.reshape((1, *shape))
            masks[name] = ok.reshape((1, *shape))
        out.append(BioTacFrames.from_channels(
            self.layout, np.array([t]), channels,
            word_valid=masks, frame_index=np.array([self._next_index]),
        ))
        self._next_index += 1
        self._last_time = t
        self.stats.frames += 1
        return out

    def _hold_pac(self, v: NDArray[np.float64], ok: NDArray[np.bool_]) -> NDArray[np.float64]:
        # pac is one signal sampled 22 (27) times: an invalid sample holds the previous
        # valid sample in time, which may be in the previous frame.
        last_good = np.maximum.accumulate(np.where(ok, np.arange(v.size), -1))
        held = np.where(last_good >= 0, v[np.maximum(last_good, 0)], self._held_pac_last)
        if ok.any():
            self._held_pac_last = float(v[np.flatnonzero(ok)[-1]])
        return held

    def _filled(self, count: int, last_time: float, period: float) -> BioTacFrames:
        n = count
        arrays = {name: np.broadcast_to(self._held[name], (n, *self.layout.shape_of(name))).copy()
                  for name in SIGNAL_CHANNELS}
        arrays["pac"][:] = self._held_pac_last
        masks = {
            name: np.zeros((n, *self.layout.shape_of(name)), dtype=bool)
            for name in SIGNAL_CHANNELS
        }
        self.stats.filled_frames += n
        return BioTacFrames.from_channels(
            self.layout,
            last_time + period * np.arange(1, n + 1),
            arrays,
            word_valid=masks,
            frame_index=self._next_index + np.arange(n),
        )
