"""The BioTac frame: what one 10 ms frame carries, and its conversion to and from SampleBatch rows.

Pure numpy; no I/O. A frame holds one sample of each slow channel (``pdc``, ``tac``, ``tdc``,
every electrode) and the ``pac`` samples interleaved between them on the wire: 22 on the
BioTac (44-word frame), 27 on the BioTac SP (54-word frame, see :mod:`._wire`). Values are
raw 12-bit ADC counts (0..4095) as float64.

Validity is kept per *word* (one bool per pac sample and per electrode) so the wire decoder
can say exactly which word failed; a SampleBatch carries one flag per channel and row, so a
channel's row is valid only when every one of its words in that frame is.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

from hapticframe.kinds import ChannelInfo, SampleBatch

__all__ = [
    "COUNT_MAX",
    "LAYOUTS",
    "SIGNAL_CHANNELS",
    "SLOT_RATE_HZ",
    "BioTacFrames",
    "FrameLayout",
    "Variant",
    "check_counts",
    "layout_for",
]

Variant = Literal["biotac", "biotac_sp"]

#: Largest 12-bit ADC count.
COUNT_MAX = 4095
#: Words sampled per second by the default firmware schedule (one word every 227 µs).
SLOT_RATE_HZ = 4400.0
#: The sensor's own channels, in SampleBatch order.
SIGNAL_CHANNELS = ("pac", "pdc", "tac", "tdc", "electrodes")


@dataclass(frozen=True)
class FrameLayout:
    """Sizes of one frame for a BioTac variant.

    Parameters
    ----------
    variant : {"biotac", "biotac_sp"}
    n_pac : int
        pac samples per frame (22 on the BioTac, 27 on the SP).
    n_electrodes : int
        Electrodes (19 on the BioTac, 24 on the SP).
    """

    variant: Variant
    n_pac: int
    n_electrodes: int

    @property
    def frame_words(self) -> int:
        """Words per frame: every electrode, pdc, tac and tdc, each followed by one pac word."""
        return 2 * (self.n_electrodes + 3)

    @property
    def frame_rate_hz(self) -> float:
        """Frames per second at the default 4400 words/s (100 Hz BioTac, ≈81.5 Hz SP)."""
        return SLOT_RATE_HZ / self.frame_words

    @property
    def frame_period_s(self) -> float:
        return 1.0 / self.frame_rate_hz

    def shape_of(self, channel: str) -> tuple[int, ...]:
        """Shape of one sample of ``channel``."""
        if channel == "pac":
            return (self.n_pac,)
        if channel == "electrodes":
            return (self.n_electrodes,)
        if channel in ("pdc", "tac", "tdc"):
            return ()
        raise KeyError(f"unknown BioTac channel {channel!r}")

    def channel_infos(
        self, ground_truth: bool = False, contact: bool | None = None
    ) -> dict[str, ChannelInfo]:
        """ChannelInfo per channel; rates are frame rates (one row per frame).

        ``ground_truth`` adds ``position_m`` and, unless ``contact`` is False, ``contact``.
        """
        rate = self.frame_rate_hz
        infos = {name: ChannelInfo(self.shape_of(name), "count", rate) for name in SIGNAL_CHANNELS}
        if ground_truth:
            infos["position_m"] = ChannelInfo((2,), "m", rate)
            if contact is None or contact:
                infos["contact"] = ChannelInfo((), "1", rate)
        return infos


LAYOUTS: dict[str, FrameLayout] = {
    "biotac": FrameLayout("biotac", n_pac=22, n_electrodes=19),
    "biotac_sp": FrameLayout("biotac_sp", n_pac=27, n_electrodes=24),
}


def layout_for(variant: str) -> FrameLayout:
    """The layout of ``variant`` (a clear ValueError for an unknown name)."""
    try:
        return LAYOUTS[variant]
    except KeyError:
        raise ValueError(
            f"unknown BioTac variant {variant!r}; expected one of {sorted(LAYOUTS)}"
        ) from None


def check_counts(values: ArrayLike, name: str) -> NDArray[np.int64]:
    """``values`` as int64 when they are integral 12-bit counts, else a ValueError naming why."""
    array = np.asarray(values, dtype=np.float64)
    if array.size and not np.isfinite(array).all():
        raise ValueError(f"{name} contains NaN or infinity; 12-bit counts must be finite")
    if array.size and (array.min() < 0 or array.max() > COUNT_MAX):
        raise ValueError(
            f"{name} spans {array.min():g}..{array.max():g}; 12-bit counts lie in 0..{COUNT_MAX}"
        )
    if array.size and not np.array_equal(array, np.round(array)):
        raise ValueError(f"{name} holds non-integer values; 12-bit counts are integers")
    return array.astype(np.int64)


def _float_rows(
    value: ArrayLike, name: str, shape: tuple[int, ...], n: int | None
) -> NDArray[np.float64]:
    array = np.asarray(value, dtype=np.float64)
    if array.ndim != 1 + len(shape) or array.shape[1:] != shape:
        dims = f"(n, {', '.join(map(str, shape))})" if shape else "(n,)"
        raise ValueError(f"{name} must have shape {dims}, got {array.shape}")
    if n is not None and array.shape[0] != n:
        raise ValueError(f"{name} has {array.shape[0]} rows, expected {n}")
    return array


@dataclass(frozen=True)
class BioTacFrames:
    """A run of consecutive BioTac frames (column arrays, one row per frame).

    Parameters
    ----------
    layout : FrameLayout
    timestamps_s : (n,) float64
        Host time of each frame, strictly increasing.
    pac : (n, n_pac) ; pdc, tac, tdc : (n,) ; electrodes : (n, n_electrodes)
        Counts as float64.
    word_valid : mapping of channel to bool array shaped like the channel, optional
        False where a word failed parity, was stale or belongs to a dropped frame. Missing
        channels are all valid.
    frame_index : (n,) int64, optional
        The decoder's frame counter; a gap means frames were dropped and skipped. Default
        ``0..n-1``.
    position_m : (n, 2), optional ; contact : (n,), optional
        Ground truth of synthetic or labelled recordings. Positions may come without
        contact labels (a real recording with the robot's positions); labels need positions.
    """

    layout: FrameLayout
    timestamps_s: NDArray[np.float64]
    pac: NDArray[np.float64]
    pdc: NDArray[np.float64]
    tac: NDArray[np.float64]
    tdc: NDArray[np.float64]
    electrodes: NDArray[np.float64]
    word_valid: Mapping[str, NDArray[np.bool_]] = field(default_factory=dict)
    frame_index: NDArray[np.int64] | None = None
    position_m: NDArray[np.float64] | None = None
    contact: NDArray[np.float64] | None = None

    def __post_init__(self) -> None:
        t = np.asarray(self.timestamps_s, dtype=np.float64)
        if t.ndim != 1:
            raise ValueError(f"timestamps_s must be one-dimensional, got shape {t.shape}")
        if t.size and not np.isfinite(t).all():
            raise ValueError("timestamps_s must be finite")
        if t.size > 1 and not (np.diff(t) > 0).all():
            raise ValueError("timestamps_s must be strictly increasing")
        n = t.size
        object.__setattr__(self, "timestamps_s", t)
        for name in SIGNAL_CHANNELS:
            rows = _float_rows(getattr(self, name), name, self.layout.shape_of(name), n)
            object.__setattr__(self, name, rows)
        masks = {}
        for name, mask in self.word_valid.items():
            if name not in SIGNAL_CHANNELS:
                raise ValueError(f"word_valid given for unknown channel {name!r}")
            mask = np.asarray(mask, dtype=bool)
            expected = (n, *self.layout.shape_of(name))
            if mask.shape != expected:
                raise ValueError(
                    f"word_valid[{name!r}] must have shape {expected}, got {mask.shape}"
                )
            masks[name] = mask
        object.__setattr__(self, "word_valid", masks)
        index = (
            np.arange(n, dtype=np.int64)
            if self.frame_index is None
            else np.asarray(self.frame_index)
        )
        if index.shape != (n,):
            raise ValueError(f"frame_index must have shape ({n},), got {index.shape}")
        object.__setattr__(self, "frame_index", index.astype(np.int64))
        if self.position_m is not None:
            position = _float_rows(self.position_m, "position_m", (2,), n)
            object.__setattr__(self, "position_m", position)
        if self.contact is not None:
            object.__setattr__(self, "contact", _float_rows(self.contact, "contact", (), n))
        if self.contact is not None and self.position_m is None:
            raise ValueError("contact labels need position_m (positions may come alone)")

    def __len__(self) -> int:
        return int(self.timestamps_s.size)

    @property
    def has_ground_truth(self) -> bool:
        return self.position_m is not None

    def channel_valid(self, channel: str) -> NDArray[np.bool_]:
        """One flag per frame: True when every word of ``channel`` in that frame is valid."""
        mask = self.word_valid.get(channel)
        if mask is None:
            return np.ones(len(self), dtype=bool)
        return np.all(mask.reshape(len(self), -1), axis=1) if mask.ndim > 1 else mask.copy()

    def to_sample_batch(self) -> SampleBatch:
        """SampleBatch rows in the shared layout (ground truth included when present).

        Every signal channel gets a validity flag per row (all True when nothing was flagged).
        """
        channels: dict[str, NDArray[np.float64]] = {
            name: getattr(self, name) for name in SIGNAL_CHANNELS
        }
        if self.position_m is not None:
            channels["position_m"] = self.position_m
        if self.contact is not None:
            channels["contact"] = self.contact
        valid = {name: self.channel_valid(name) for name in SIGNAL_CHANNELS}
        return SampleBatch(self.timestamps_s, channels, valid)

    @classmethod
    def from_channels(
        cls,
        layout: FrameLayout,
        timestamps_s: ArrayLike,
        signals: Mapping[str, ArrayLike],
        *,
        word_valid: Mapping[str, NDArray[np.bool_]] | None = None,
        frame_index: ArrayLike | None = None,
        position_m: ArrayLike | None = None,
        contact: ArrayLike | None = None,
    ) -> BioTacFrames:
        """Frames from a mapping of every name in ``SIGNAL_CHANNELS`` to its column array."""
        return cls(
            layout,
            np.asarray(timestamps_s, dtype=np.float64),
            pac=np.asarray(signals["pac"], dtype=np.float64),
            pdc=np.asarray(signals["pdc"], dtype=np.float64),
            tac=np.asarray(signals["tac"], dtype=np.float64),
            tdc=np.asarray(signals["tdc"], dtype=np.float64),
            electrodes=np.asarray(signals["electrodes"], dtype=np.float64),
            word_valid={} if word_valid is None else word_valid,
            frame_index=None if frame_index is None else np.asarray(frame_index),
            position_m=None if position_m is None else np.asarray(position_m, dtype=np.float64),
            contact=None if contact is None else np.asarray(contact, dtype=np.float64),
        )

    @classmethod
    def from_sample_batch(cls, batch: SampleBatch, variant: str = "biotac") -> BioTacFrames:
        """Frames from SampleBatch rows; a channel's row flag becomes the flag of all its words."""
        layout = layout_for(variant)
        missing = [name for name in SIGNAL_CHANNELS if name not in batch.channels]
        if missing:
            raise ValueError(f"the batch lacks BioTac channel(s) {missing}")
        n = len(batch)
        word_valid = {
            name: np.broadcast_to(
                np.asarray(batch.valid[name]).reshape((n,) + (1,) * len(layout.shape_of(name))),
                (n, *layout.shape_of(name)),
            ).copy()
            for name in SIGNAL_CHANNELS
            if name in batch.valid
        }
        position = "position_m" in batch.channels
        truth = position and "contact" in batch.channels
        return cls.from_channels(
            layout,
            np.array(batch.timestamps_s),
            {name: np.array(batch.channels[name]) for name in SIGNAL_CHANNELS},
            word_valid=word_valid,
            position_m=np.array(batch.channels["position_m"]) if position else None,
            contact=np.array(batch.channels["contact"]) if truth else None,
        )

    @property
    def has_contact_labels(self) -> bool:
        return self.contact is not None

    def select(self, rows: slice | NDArray[np.intp] | NDArray[np.bool_]) -> BioTacFrames:
        """The frames at ``rows``."""
        assert self.frame_index is not None  # __post_init__ fills it in
        return BioTacFrames.from_channels(
            self.layout,
            self.timestamps_s[rows],
            {name: getattr(self, name)[rows] for name in SIGNAL_CHANNELS},
            word_valid={k: v[rows] for k, v in self.word_valid.items()},
            frame_index=self.frame_index[rows],
            position_m=None if self.position_m is None else self.position_m[rows],
            contact=None if self.contact is None else self.contact[rows],
        )

    @classmethod
    def empty(
        cls, layout: FrameLayout, ground_truth: bool = False, contact: bool | None = None
    ) -> BioTacFrames:
        """No frames; ``ground_truth`` gives positions, and contact labels unless ``contact``
        says otherwise."""
        labels = ground_truth if contact is None else contact
        return cls(
            layout,
            np.empty(0),
            np.empty((0, layout.n_pac)),
            np.empty(0),
            np.empty(0),
            np.empty(0),
            np.empty((0, layout.n_electrodes)),
            position_m=np.empty((0, 2)) if ground_truth else None,
            contact=np.empty(0) if labels else None,
        )

    @staticmethod
    def concatenate(parts: Sequence[BioTacFrames]) -> BioTacFrames:
        """Join consecutive runs of frames of one layout."""
        if not parts:
            raise ValueError("need at least one run of frames to concatenate")
        layout = parts[0].layout
        if any(p.layout != layout for p in parts):
            raise ValueError("cannot join frames of different BioTac variants")
        truth = {(p.has_ground_truth, p.has_contact_labels) for p in parts}
        if len(truth) > 1:
            raise ValueError("cannot join frames with and without ground truth")
        names = {k for p in parts for k in p.word_valid}
        word_valid = {
            k: np.concatenate(
                [
                    p.word_valid.get(k, np.ones((len(p), *layout.shape_of(k)), dtype=bool))
                    for p in parts
                ]
            )
            for k in names
        }
        frame_indices = [p.frame_index for p in parts if p.frame_index is not None]
        positions = [p.position_m for p in parts if p.position_m is not None]
        contacts = [p.contact for p in parts if p.contact is not None]
        has_truth, has_labels = truth.pop()
        return BioTacFrames.from_channels(
            layout,
            np.concatenate([p.timestamps_s for p in parts]),
            {name: np.concatenate([getattr(p, name) for p in parts]) for name in SIGNAL_CHANNELS},
            word_valid=word_valid,
            frame_index=np.concatenate(frame_indices),
            position_m=np.concatenate(positions) if has_truth else None,
            contact=np.concatenate(contacts) if has_labels else None,
        )
