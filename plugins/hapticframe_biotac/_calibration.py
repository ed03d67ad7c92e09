"""Calibration of the synthetic BioTac from real recordings: what the generator must match.

:func:`calibrate_biotac` reads real recordings (raw counts, each starting at rest in open
air, such as the Penn BOLT trials) and measures, with the contact reference "derived from
pdc" (:mod:`._reference`) splitting free from contact frames:

- **resting levels** of pdc, the 19 electrodes, pac's centre, tac and tdc (mean over the
  first ``rest_frames`` of each recording) and their spread across recordings;
- **resting noise** (standard deviation over those frames, per channel and electrode);
- **drift**: the slope (counts/s) of pdc and of each electrode over the free frames after
  the first contact, across recordings;
- **pac noise spectrum** at rest (Welch's power in octave bands from 12.5 Hz to 1.1 kHz of
  the 2.2 kHz stream) and its amplitude; the vibration of a press, as the rise of pac's
  per-frame standard deviation with the frame's pdc change (least squares,
  ``pac_std = base + gain·|Δpdc|``);
- **press responses**: every contact episode's duration, peak and mean pdc rise and its rise
  and fall times, per recording in order with the gaps between them and the time of the
  first contact (kept as a table: the generator resamples a recording's protocol), and
  each electrode's change per count of pdc rise (least squares over the contact frames,
  per fingertip position in the recording list's ``finger`` order) with the residual spread
  (shear and slip that pdc does not explain).

The result is a :class:`BioTacCalibration`: plain numbers, saved as JSON
(:meth:`BioTacCalibration.save`, :meth:`BioTacCalibration.load`) and read by
:func:`hapticframe_biotac.generate_press_trial`.
"""

from __future__ import annotations

import itertools
import json
from collections.abc import Mapping, Sequence
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ._frame import BioTacFrames
from ._reference import PdcReference

__all__ = ["PAC_BANDS_HZ", "BioTacCalibration", "calibrate_biotac", "pac_band_power",
           "recording_statistics"]

FloatArray = NDArray[np.float64]
PAC_RATE_HZ = 2200.0
#: Octave band edges (Hz) of the pac spectrum.
PAC_BANDS_HZ = (12.5, 25.0, 50.0, 100.0, 200.0, 400.0, 800.0, 1100.0)
FORMAT = "hapticframe-biotac-calibration"


@dataclass(frozen=True)
class BioTacCalibration:
    """The synthetic press generator's parameters, measured on real recordings.

    Every field is a plain number or list (JSON). Counts are raw 12-bit counts; times are
    seconds; ``electrode_gain`` has one row of 19 per fingertip.
    """

    rest_pdc: float
    rest_pdc_spread: float
    rest_electrodes: list[float]
    rest_electrodes_spread: list[float]
    rest_pac: float
    rest_tac: float
    rest_tdc: float
    noise_pdc: float
    noise_electrodes: list[float]
    noise_pac: float
    noise_tac: float
    noise_tdc: float
    drift_pdc_per_s: float
    drift_electrodes_per_s: float
    pac_band_rms: list[float]
    pac_press_base: float
    pac_press_gain: float
    episodes: list[list[dict[str, float]]]
    first_contact_s: list[float]
    gaps_s: list[list[float]]
    electrode_gain: list[list[float]]
    electrode_residual: list[float]
    recording_s: list[float]
    reference: dict[str, Any]
    recordings: int

    def as_dict(self) -> dict[str, Any]:
        return {"format": FORMAT, "version": 1, **asdict(self)}

    def save(self, path: str | Path) -> Path:
        """Write the parameters as JSON (the generator's input)."""
        path = Path(path)
        path.write_text(json.dumps(self.as_dict(), indent=1, allow_nan=False) + "\n")
        return path

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> BioTacCalibration:
        """Parameters from :meth:`as_dict`'s form (ValueError naming a missing field)."""
        if data.get("format") != FORMAT:
            raise ValueError(f"not a BioTac calibration (format {data.get('format')!r})")
        fields = set(cls.__dataclass_fields__)
        missing = sorted(fields - set(data))
        if missing:
            raise ValueError(f"the calibration lacks {', '.join(missing)}")
        return cls(**{k: data[k] for k in fields})

    @classmethod
    def load(cls, path: str | Path) -> BioTacCalibration:
        try:
            data = json.loads(Path(path).read_text())
        except (OSError, json.JSONDecodeError) as exc:
            raise ValueError(f"{path}: cannot read a calibration ({exc})") from None
        try:
            return cls.from_dict(data)
        except ValueError as exc:
            raise ValueError(f"{path}: {exc}") from None


def pac_band_power(pac: FloatArray, rate_hz: float = PAC_RATE_HZ) -> FloatArray:
    """RMS (counts) of a pac stream in each octave band of :data:`PAC_BANDS_HZ` (periodogram
    averaged over 256-sample Hann segments, Welch's method)."""
    x = np.asarray(pac, dtype=np.float64).ravel()
    x = x - x.mean()
    seg = 256
    if x.size < seg:
        return np.zeros(len(PAC_BANDS_HZ) - 1)
    window = np.hanning(seg)
    starts = range(0, x.size - seg + 1, seg // 2)
    power = np.mean([np.abs(np.fft.rfft(window * x[s:s + seg])) ** 2 for s in starts], axis=0)
    power *= 2.0 / (rate_hz * np.sum(window**2))  # one-sided density, counts²/Hz
    freqs = np.fft.rfftfreq(seg, 1.0 / rate_hz)
    df = freqs[1]
    bands = []
    for lo, hi in itertools.pairwise(PAC_BANDS_HZ):
        inside = (freqs >= lo) & (freqs < hi)
        bands.append(float(np.sqrt(np.sum(power[inside]) * df)))
    return np.array(bands)


def _episodes(labels: NDArray[np.int8]) -> list[tuple[int, int]]:
    edges = np.diff(np.concatenate([[0], labels.astype(np.int64), [0]]))
    return list(zip(np.flatnonzero(edges == 1), np.flatnonzero(edges == -1), strict=True))


def _crossing_time(rise: FloatArray, peak: float, forward: bool) -> float:
    """Seconds from the episode's edge to 90 % of its peak (or back from it)."""
    values = rise if forward else rise[::-1]
    above = np.flatnonzero(values >= 0.9 * peak)
    return 0.01 * float(above[0]) if above.size else 0.01 * values.size


def recording_statistics(frames: BioTacFrames, reference: PdcReference) -> dict[str, Any]:
    """The statistics of one recording that :func:`calibrate_biotac` pools."""
    n = len(frames)
    rest = reference.rest_frames
    labels = reference(frames.pdc)
    pdc_rest = float(frames.pdc[:rest].mean())
    rise = frames.pdc - pdc_rest
    electrodes = frames.electrodes - frames.electrodes[:rest].mean(axis=0)
    t = frames.timestamps_s
    episodes = []
    for a, b in _episodes(labels):
        r = rise[a:b]
        peak = float(r.max())
        episodes.append({"duration_s": 0.01 * (b - a), "peak": peak,
                         "mean": float(r.mean()),
                         "rise_s": _crossing_time(r, peak, True),
                         "fall_s": _crossing_time(r, peak, False)})
    bounds = _episodes(labels)
    gaps = [0.01 * float(bounds[i + 1][0] - bounds[i][1]) for i in range(len(bounds) - 1)]
    # Drift: a line through the free frames after the first contact.
    free = labels == 0
    free[: bounds[0][0] if bounds else n] = False
    drift_pdc = drift_e = None
    if free.sum() > 200:
        design = np.column_stack([t[free], np.ones(free.sum())])
        drift_pdc = float(np.linalg.lstsq(design, frames.pdc[free], rcond=None)[0][0])
        drift_e = np.linalg.lstsq(design, frames.electrodes[free], rcond=None)[0][0]
    contact = labels == 1
    gain = residual = None
    if contact.sum() > 20:
        gain = np.linalg.lstsq(rise[contact, None], electrodes[contact], rcond=None)[0][0]
        residual = (electrodes[contact] - np.outer(rise[contact], gain)).std(axis=0)
    pac_std = frames.pac.std(axis=1)
    dpdc = np.abs(np.diff(frames.pdc, prepend=frames.pdc[0]))
    return {
        "rest": {"pdc": pdc_rest, "electrodes": frames.electrodes[:rest].mean(axis=0),
                 "pac": float(frames.pac[:rest].mean()), "tac": float(frames.tac[:rest].mean()),
                 "tdc": float(frames.tdc[:rest].mean())},
        "noise": {"pdc": float(frames.pdc[:rest].std()),
                  "electrodes": frames.electrodes[:rest].std(axis=0),
                  "pac": float((frames.pac[:rest] - frames.pac[:rest].mean(axis=1,
                                                                          keepdims=True)).std()),
                  "tac": float(frames.tac[:rest].std()), "tdc": float(frames.tdc[:rest].std())},
        "pac_bands": pac_band_power(frames.pac[:rest]),
        "pac_frame_std": pac_std, "abs_dpdc": dpdc,
        "episodes": episodes, "gaps_s": gaps,
        "first_contact_s": 0.01 * float(bounds[0][0]) if bounds else None,
        "drift_pdc": drift_pdc, "drift_electrodes": drift_e,
        "electrode_gain": gain, "electrode_residual": residual, "duration_s": 0.01 * n,
    }


def calibrate_biotac(
    recordings: Sequence[BioTacFrames], fingers: Sequence[int] | None = None, *,
    reference: Mapping[str, Any] | None = None,
) -> BioTacCalibration:
    """Measure the generator's parameters on real ``recordings`` (see the module notes).

    Parameters
    ----------
    recordings : sequence of BioTacFrames
        Raw counts, each starting with at least ``rest_frames`` frames at rest in air.
    fingers : sequence of int, optional
        The fingertip of each recording (0 or 1; electrode gains are kept per fingertip);
        default: alternating 0, 1 (the order :func:`hapticframe_biotac.load_bolt` gives).
    reference : mapping, optional
        :class:`PdcReference` settings (default 100 resting frames, on 20, off 10 counts).

    Raises
    ------
    ValueError
        No recordings, or none with a contact by the reference.
    """
    ref = PdcReference(**dict(reference or {}))
    if not recordings:
        raise ValueError("calibration needs at least one recording")
    fingers = list(fingers) if fingers is not None else [i % 2 for i in range(len(recordings))]
    stats = [recording_statistics(f, ref) for f in recordings]
    if not any(s["episodes"] for s in stats):
        raise ValueError("no recording has a contact by the reference derived from pdc; "
                         "nothing to calibrate the press response on")

    def pooled(key: str, sub: str) -> FloatArray:
        return np.array([s[key][sub] for s in stats], dtype=np.float64)

    gains: list[list[float]] = []
    for finger in sorted(set(fingers)):
        rows = [s["electrode_gain"] for s, f in zip(stats, fingers, strict=True)
                if f == finger and s["electrode_gain"] is not None]
        if rows:
            gains.append(np.median(rows, axis=0).tolist())
    residuals = [s["electrode_residual"] for s in stats if s["electrode_residual"] is not None]
    pac_std = np.concatenate([s["pac_frame_std"] for s in stats])
    dpdc = np.concatenate([s["abs_dpdc"] for s in stats])
    base, slope = np.linalg.lstsq(np.column_stack([np.ones(dpdc.size), dpdc]), pac_std,
                                  rcond=None)[0]
    drifts_pdc = [s["drift_pdc"] for s in stats if s["drift_pdc"] is not None]
    drifts_e = [s["drift_electrodes"] for s in stats if s["drift_electrodes"] is not None]
    electrodes_rest = pooled("rest", "electrodes")
    return BioTacCalibration(
        rest_pdc=float(pooled("rest", "pdc").mean()),
        rest_pdc_spread=float(pooled("rest", "pdc").std()),
        rest_electrodes=electrodes_rest.mean(axis=0).tolist(),
        rest_electrodes_spread=electrodes_rest.std(axis=0).tolist(),
        rest_pac=float(pooled("rest", "pac").mean()),
        rest_tac=float(pooled("rest", "tac").mean()),
        rest_tdc=float(pooled("rest", "tdc").mean()),
        noise_pdc=float(np.median(pooled("noise", "pdc"))),
        noise_electrodes=np.median(pooled("noise", "electrodes"), axis=0).tolist(),
        noise_pac=float(np.median(pooled("noise", "pac"))),
        noise_tac=float(np.median(pooled("noise", "tac"))),
        noise_tdc=float(np.median(pooled("noise", "tdc"))),
        drift_pdc_per_s=float(np.std(drifts_pdc)) if drifts_pdc else 0.0,
        drift_electrodes_per_s=float(np.std(drifts_e)) if drifts_e else 0.0,
        pac_band_rms=np.median([s["pac_bands"] for s in stats], axis=0).tolist(),
        pac_press_base=float(max(base, 0.0)),
        pac_press_gain=float(max(slope, 0.0)),
        episodes=[s["episodes"] for s in stats if s["episodes"]],
        first_contact_s=[s["first_contact_s"] for s in stats if s["episodes"]],
        gaps_s=[s["gaps_s"] for s in stats if s["episodes"]],
        electrode_gain=gains,
        electrode_residual=(np.median(residuals, axis=0).tolist() if residuals
                            else [0.0] * 19),
        recording_s=[s["duration_s"] for s in stats],
        reference=ref.as_dict(),
        recordings=len(recordings),
    )
