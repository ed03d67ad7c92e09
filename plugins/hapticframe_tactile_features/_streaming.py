"""Streaming EMD feature tensors on ring buffers, with an explicit look-ahead delay.

Every 10 ms frame the BioTac delivers 22 pac samples, one pdc sample and one value per
electrode. :class:`FeatureStream` appends them to ring buffers and decomposes the whole pac
and pdc windows each frame. The newest samples sit at the window's end, where EMD's end
effects live (about 40 % error on IMF1 of the newest 10 ms without look-ahead; see
``shared/notes/perception.md`` §1.6), so the features emitted after frame ``k`` describe
frame ``j = k - delay_frames``: its 22 pac samples lie ``22 * delay_frames`` samples
inside the window's end. The emitted tensors are

- ``pac_imfs`` (pac_imfs, 22): the pac IMFs over frame ``j``'s samples;
- ``pdc_imfs`` (pdc_imfs, 5): the pdc IMFs over frames ``j-4 .. j``;
- ``electrodes_window`` (electrodes, 5): the raw electrodes of frames ``j-4 .. j``.

The batch path of the extractor is this stream run over a whole recording from a fresh
state, so training features and run-time features come from the same code, the same
windows and the same delay; the last ``delay_frames`` frames of a recording have no
features (their look-ahead never arrives).

Start of a stream and invalid samples
-------------------------------------
- The stream starts at the first frame in which every consumed channel is valid (finite and
  not flagged in ``SampleBatch.valid``); frames before it are dropped without output.
- At the start every ring buffer is filled with that first frame's values (for pac, its
  first sample), so the first windows hold a constant history instead of zeros.
- After the start, an invalid value (NaN, infinity, or a channel flagged invalid) takes the
  last valid value of the same element (sample-and-hold, as a parity drop on the BioTac bus
  would look), and the output frame is flagged invalid in the result's ``valid`` mask.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ._config import ELECTRODE_FRAMES, PDC_FRAMES, EMDFeaturesConfig, Modality, feature_channel
from ._emd import MIN_SAMPLES, _use_kernel, emd
from ._validation import as_count, as_real

__all__ = ["FeatureStream", "RingBuffer", "hold_invalid"]

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]


class RingBuffer:
    """A fixed-capacity FIFO of samples with a contiguous, oldest-first view.

    Each value is written twice, at ``i`` and ``i + capacity`` of a buffer of twice the
    capacity, so the chronological window is always one contiguous slice (no copy, no
    ``np.roll``).
    """

    def __init__(self, capacity: int, sample_shape: tuple[int, ...] = ()) -> None:
        if capacity < 1:
            raise ValueError("ring buffer capacity must be at least 1")
        self.capacity = int(capacity)
        self._data = np.zeros((2 * self.capacity, *sample_shape))
        self._start = 0

    def fill(self, value: FloatArray | float) -> None:
        """Set every slot to ``value`` (one sample)."""
        self._data[...] = value
        self._start = 0

    def push(self, values: FloatArray) -> None:
        """Append samples ``values`` (shape ``(n, *sample_shape)``), dropping the oldest."""
        n = values.shape[0]
        if n >= self.capacity:
            values = values[n - self.capacity :]
            n = self.capacity
        # At most two contiguous runs of slots (before and after the wrap): slices, not a
        # fancy index, since this runs for every channel of every frame.
        first = min(n, self.capacity - self._start)
        for offset in (0, self.capacity):
            begin = self._start + offset
            self._data[begin : begin + first] = values[:first]
            self._data[offset : offset + n - first] = values[first:]
        self._start = (self._start + n) % self.capacity

    def push_one(self, value: FloatArray | float) -> None:
        """Append one sample (what :meth:`push` does for ``n = 1``, with less bookkeeping:
        the stream pushes one sample per channel and frame)."""
        self._data[self._start] = value
        self._data[self._start + self.capacity] = value
        self._start = (self._start + 1) % self.capacity

    def view(self) -> FloatArray:
        """The window, oldest sample first (a read-only view)."""
        window = self._data[self._start : self._start + self.capacity]
        window.flags.writeable = False
        return window


def hold_invalid(values: FloatArray, valid: BoolArray, held: FloatArray) -> FloatArray:
    """Replace invalid samples by the last valid one along axis 0 (sample-and-hold).

    Parameters
    ----------
    values : (n, ...) float64
    valid : (n, ...) bool
        Element-wise validity.
    held : (...) float64
        The last valid value before ``values[0]``.
    """
    if valid.all():
        return values.copy()
    out = np.concatenate((held[np.newaxis], values), axis=0)
    ok = np.concatenate((np.ones((1, *held.shape), dtype=bool), valid), axis=0)
    index = np.where(ok, np.arange(out.shape[0]).reshape(-1, *([1] * held.ndim)), 0)
    source = np.maximum.accumulate(index, axis=0)
    return np.take_along_axis(out, source, axis=0)[1:]


class _Decomposer:
    """:func:`._emd.emd` of one window length with fixed settings, checked once.

    Every frame decomposes the pac and pdc windows; :func:`._emd.emd` re-checks its
    settings, re-resolves the backend and allocates its outputs on every call, and computes
    the residue, which the stream does not use. Here the settings are checked and the
    backend resolved at construction, and the compiled kernel writes into buffers reused
    from frame to frame (:meth:`__call__` returns them: copy what is kept). Without the
    kernel (numpy backend) it calls :func:`._emd.emd` itself.
    """

    def __init__(self, samples: int, max_imfs: int, config: EMDFeaturesConfig) -> None:
        self.max_imfs = as_count("max_imfs", max_imfs)
        self.max_sifts = as_count("max_sifts", config.max_sifts)
        self.n_mirror = as_count("n_mirror", config.mirrored_extrema)
        self.sd_threshold = as_real("sd_threshold", config.sd_threshold)
        self.residue_ratio = as_real("residue_ratio", config.residue_ratio)
        self.backend = config.emd_backend
        self.kernel = _use_kernel(config.emd_backend) and samples >= MIN_SAMPLES
        self._imfs = np.zeros((self.max_imfs, samples))
        self._counts = np.zeros(self.max_imfs, dtype=np.int64)
        self._kernel: Any = None
        self._status: tuple[int, int] = (0, 0)
        if self.kernel:  # imports numba, so only when the kernel will run
            from ._emd_kernel import STATUS_CONSTANT, STATUS_OK, emd_kernel

            self._kernel = emd_kernel
            self._status = (STATUS_OK, STATUS_CONSTANT)

    def __call__(self, window: FloatArray) -> tuple[FloatArray, int]:
        """IMFs (max_imfs, samples) of ``window`` (finite: the stream holds invalid samples)
        and how many were found (the rest are zero rows)."""
        if not self.kernel:
            result = emd(window, self.max_imfs, sd_threshold=self.sd_threshold,
                         max_sifts=self.max_sifts, residue_ratio=self.residue_ratio,
                         n_mirror=self.n_mirror, backend=self.backend)
            return result.imfs, result.n_found
        self._imfs.fill(0.0)
        self._counts.fill(0)
        found, status = self._kernel(window, self._imfs, self._counts, self.sd_threshold,
                                   self.max_sifts, self.residue_ratio, self.n_mirror)
        ok, constant = self._status
        if status == constant:
            return self._imfs, 0
        if status != ok:
            raise ValueError("spline system is singular; knots must differ")
        return self._imfs, int(found)


@dataclass(frozen=True)
class _Frame:
    """One frame's values for each consumed modality, and whether all of them were valid."""

    values: dict[Modality, FloatArray]
    valid: dict[Modality, BoolArray]


class FeatureStream:
    """The EMD feature tensors of a BioTac stream, one output per frame after the delay.

    Parameters
    ----------
    config : EMDFeaturesConfig
    """

    def __init__(self, config: EMDFeaturesConfig) -> None:
        self.config = config
        self.modalities: tuple[Modality, ...] = tuple(config.modalities)
        self.delay = int(config.delay_frames)
        self._pac = RingBuffer(config.pac_window_samples)
        self._pdc = RingBuffer(config.pdc_window_samples)
        self._electrodes = RingBuffer(ELECTRODE_FRAMES + self.delay, (config.electrode_count,))
        self._times = RingBuffer(self.delay + 1)
        self._frame_ok = {m: RingBuffer(self.delay + 1) for m in self.modalities}
        self._decompose_pac = _Decomposer(config.pac_window_samples, config.pac_imfs, config)
        self._decompose_pdc = _Decomposer(config.pdc_window_samples, config.pdc_imfs, config)
        self.reset()

    @property
    def sample_shapes(self) -> dict[Modality, tuple[int, ...]]:
        """Per-frame input shape of each consumed modality."""
        shapes: dict[Modality, tuple[int, ...]] = {
            "pac": (self.config.pac_samples_per_frame,),
            "pdc": (),
            "electrodes": (self.config.electrode_count,),
        }
        return {m: shapes[m] for m in self.modalities}

    @property
    def output_shapes(self) -> dict[str, tuple[int, ...]]:
        """Shape of one output tensor per feature channel."""
        shapes = {
            "pac": (self.config.pac_imfs, self.config.pac_samples_per_frame),
            "pdc": (self.config.pdc_imfs, PDC_FRAMES),
            "electrodes": (self.config.electrode_count, ELECTRODE_FRAMES),
        }
        return {feature_channel(m): shapes[m] for m in self.modalities}

    def reset(self) -> None:
        """Forget the history: the next frame is treated as a stream's first."""
        self._started = False
        self._frames = 0
        self._held: dict[Modality, FloatArray] = {}
        #: IMFs actually found in the latest pac and pdc windows (the rest are zero rows).
        self.imf_counts: dict[Modality, int] = {}

    # -- one frame ---------------------------------------------------------------------

    def _accept(self, frame: _Frame) -> bool:
        """Sanitise and buffer one frame; False while the stream has not started."""
        if not self._started:
            if not all(bool(frame.valid[m].all()) for m in self.modalities):
                return False
            self._start(frame)
        for m in self.modalities:
            held = self._held[m]
            all_valid = bool(frame.valid[m].all())
            if m == "pac":  # hold along the sample sequence, within and across frames
                clean = hold_invalid(frame.values[m], frame.valid[m], held)
                self._held[m] = clean[-1:].reshape(())
                self._pac.push(clean)
            else:
                # Copied either way: the held value must not share the caller's array.
                clean = (frame.values[m].copy() if all_valid
                         else np.where(frame.valid[m], frame.values[m], held))
                self._held[m] = clean
                (self._pdc if m == "pdc" else self._electrodes).push_one(clean)
            self._frame_ok[m].push_one(float(all_valid))
        return True

    def _start(self, frame: _Frame) -> None:
        for m in self.modalities:
            first = frame.values[m]
            if m == "pac":
                self._held[m] = np.asarray(first[0])
                self._pac.fill(first[0])
            elif m == "pdc":
                self._held[m] = np.asarray(first)
                self._pdc.fill(first)
            else:
                self._held[m] = first.copy()
                self._electrodes.fill(first)
            self._frame_ok[m].fill(1.0)
        self._started = True
        self._frames = 0

    def _features(self) -> dict[str, FloatArray]:
        cfg = self.config
        out: dict[str, FloatArray] = {}
        # The decomposers reuse their buffers: each slice kept is copied.
        if "pac" in self.modalities:
            imfs, self.imf_counts["pac"] = self._decompose_pac(self._pac.view())
            end = cfg.pac_window_samples - cfg.pac_samples_per_frame * self.delay
            out["pac_imfs"] = imfs[:, end - cfg.pac_samples_per_frame : end].copy()
        if "pdc" in self.modalities:
            imfs, self.imf_counts["pdc"] = self._decompose_pdc(self._pdc.view())
            end = cfg.pdc_window_samples - self.delay
            out["pdc_imfs"] = imfs[:, end - PDC_FRAMES : end].copy()
        if "electrodes" in self.modalities:
            out["electrodes_window"] = self._electrodes.view()[:ELECTRODE_FRAMES].T.copy()
        return out

    # -- many frames -------------------------------------------------------------------

    def process(
        self,
        timestamps_s: FloatArray,
        values: Mapping[Modality, FloatArray],
        frame_valid: Mapping[Modality, BoolArray] | None = None,
    ) -> tuple[FloatArray, dict[str, FloatArray], dict[str, BoolArray]]:
        """Consume frames; return the times, tensors and validity of the features now due.

        Parameters
        ----------
        timestamps_s : (n,) float64
            Frame times.
        values : mapping of modality to (n, *sample_shape) float64
            One array per consumed modality.
        frame_valid : mapping of modality to (n,) bool, optional
            Frame-level validity from the sensor (missing means valid).

        Returns
        -------
        times : (n_out,) float64
            Times of the frames the features describe (``delay_s`` before the newest input).
        tensors : dict of str to (n_out, *shape) float64
        valid : dict of str to (n_out,) bool
            False where the described frame held invalid samples.
        """
        n = timestamps_s.shape[0]
        shapes = self.sample_shapes
        for m in self.modalities:
            if m not in values:
                raise ValueError(f"input lacks the {m!r} channel this extractor is configured for")
            if values[m].shape != (n, *shapes[m]):
                raise ValueError(
                    f"{m!r} has shape {values[m].shape}, expected {(n, *shapes[m])} "
                    "(one row per frame)"
                )
        flags = frame_valid or {}
        times: list[float] = []
        rows: dict[str, list[FloatArray]] = {name: [] for name in self.output_shapes}
        oks: dict[str, list[bool]] = {name: [] for name in self.output_shapes}
        for i in range(n):
            frame_values = {m: values[m][i] for m in self.modalities}
            frame_ok = {}
            for m in self.modalities:
                ok = np.isfinite(frame_values[m])
                if m in flags and not flags[m][i]:
                    ok = np.zeros_like(ok)
                frame_ok[m] = ok
            self._times.push_one(timestamps_s[i])
            if not self._accept(_Frame(frame_values, frame_ok)):
                continue
            self._frames += 1
            if self._frames <= self.delay:
                continue
            times.append(float(self._times.view()[0]))
            for name, tensor in self._features().items():
                rows[name].append(tensor)
            for m in self.modalities:
                oks[feature_channel(m)].append(bool(self._frame_ok[m].view()[0] > 0.5))
        tensors = {
            name: np.array(rows[name]).reshape(len(times), *shape)
            for name, shape in self.output_shapes.items()
        }
        valid = {name: np.array(oks[name], dtype=bool) for name in self.output_shapes}
        return np.array(times, dtype=np.float64), tensors, valid
