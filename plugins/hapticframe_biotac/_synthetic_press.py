"""Synthetic press trials from a calibration measured on real recordings.

:func:`generate_press_trial` draws a trial like the Penn BOLT ones — the fingertip at rest
in open air, then contact episodes (presses, holds, releases) separated by free spells —
with every statistic taken from a :class:`~._calibration.BioTacCalibration`:

- length: a measured recording's; the protocol (time of first contact, the contact episodes
  in order and the gaps between them) that of a measured recording drawn at random, each
  episode's peak, mean and times scaled by log-normal(0.15) factors;
- each episode's pdc rise shaped as a ramp to the peak in its rise time, a settle to the
  level that gives its mean, and a ramp down in its fall time;
- resting levels with their measured spread, drift (counts/s, one slope per trial), resting
  noise per channel;
- electrodes: the measured change per count of pdc rise of one fingertip (drawn), scaled per
  episode by a log-normal(0.2) factor, plus the measured residual spread as slow
  (0.5 s) coloured noise weighted by the load;
- pac: resting noise shaped to the measured octave-band spectrum, plus vibration whose
  per-frame standard deviation follows the measured ``base + gain·|Δpdc|``.

No contact label is written: the reference is derived from pdc
(:func:`hapticframe_biotac.derived_from_pdc`), as for the real trials.
"""

from __future__ import annotations

import itertools

import numpy as np
from numpy.typing import NDArray

from ._calibration import PAC_BANDS_HZ, PAC_RATE_HZ, BioTacCalibration
from ._frame import BioTacFrames, layout_for
from ._synthetic_media import colored_noise

__all__ = ["generate_press_trial"]

FloatArray = NDArray[np.float64]
_FRAME_S = 0.01
_N_PAC = 22


def _episode_shape(rng: np.random.Generator, episode: dict[str, float]) -> FloatArray:
    """One episode's pdc rise (counts) frame by frame, with a lead-in and lead-out below the
    reference's threshold."""
    n = max(3, round(episode["duration_s"] / _FRAME_S))
    peak = max(float(episode["peak"]), 1.0)
    level = float(np.clip(episode["mean"], 0.3 * peak, peak))
    up = int(np.clip(round(episode["rise_s"] / _FRAME_S), 1, n - 1))
    down = int(np.clip(round(episode["fall_s"] / _FRAME_S), 1, max(1, n - up)))
    hold = max(0, n - up - down)
    settle = np.linspace(peak, level, hold) if hold else np.empty(0)
    # Lead-in/out frames: the rise below the reference's threshold before and after.
    lead = int(rng.integers(2, 6))
    return np.concatenate([np.linspace(0.0, peak, up + lead, endpoint=False), settle,
                           np.linspace(settle[-1] if hold else peak, 0.0, down + lead)])


def _shaped_pac_noise(rng: np.random.Generator, samples: int, band_rms: FloatArray
                      ) -> FloatArray:
    """Gaussian noise whose octave-band RMS follows ``band_rms`` (flat within a band)."""
    if samples == 0 or not np.any(band_rms > 0):
        return np.zeros(samples)
    freqs = np.fft.rfftfreq(samples, 1.0 / PAC_RATE_HZ)
    amplitude = np.zeros(freqs.size)
    for (lo, hi), rms in zip(itertools.pairwise(PAC_BANDS_HZ), band_rms,
                             strict=True):
        amplitude[(freqs >= lo) & (freqs < hi)] = rms / np.sqrt(hi - lo)
    spectrum = np.fft.rfft(rng.standard_normal(samples)) * amplitude
    noise = np.fft.irfft(spectrum, samples)
    scale = np.sqrt(np.sum(np.asarray(band_rms) ** 2)) / max(float(noise.std()), 1e-12)
    return noise * scale


def generate_press_trial(calibration: BioTacCalibration, rng: np.random.Generator,
                         n_frames: int | None = None, finger: int | None = None
                         ) -> BioTacFrames:
    """One synthetic press trial in raw 12-bit counts (see the module notes).

    ``n_frames`` None draws the length of a measured recording; ``finger`` None draws the
    fingertip whose electrode response it takes.
    """
    cal = calibration
    n = int(n_frames if n_frames is not None
            else round(float(rng.choice(cal.recording_s)) / _FRAME_S))
    rest_frames = int(cal.reference.get("rest_frames", 100))
    if n < rest_frames + 10:
        raise ValueError(f"a press trial needs more than {rest_frames + 10} frames, got {n}")
    t = np.arange(n, dtype=np.float64) * _FRAME_S
    rise = np.zeros(n)
    weights = np.zeros(n)  # per-episode electrode scale
    protocol = int(rng.integers(len(cal.episodes)))
    start = max(cal.first_contact_s[protocol] * rng.lognormal(0.0, 0.15),
                (rest_frames + 50) * _FRAME_S)
    at = round(start / _FRAME_S)
    gaps = [*cal.gaps_s[protocol], 0.0]
    for episode, gap in zip(cal.episodes[protocol], gaps, strict=True):
        jittered = {k: v * rng.lognormal(0.0, 0.15) for k, v in episode.items()}
        shape = _episode_shape(rng, jittered)
        stop = min(n, at + shape.size)
        if at >= n - 10:
            break
        rise[at:stop] += shape[: stop - at]
        weights[at:stop] = rng.lognormal(0.0, 0.2)
        at = stop + max(10, round(gap * rng.lognormal(0.0, 0.15) / _FRAME_S))

    pdc = (cal.rest_pdc + rng.normal(0.0, cal.rest_pdc_spread)
           + rng.normal(0.0, cal.drift_pdc_per_s) * t + rise
           + rng.normal(0.0, cal.noise_pdc, n))

    if finger is None:
        finger = int(rng.integers(len(cal.electrode_gain)))
    if not 0 <= finger < len(cal.electrode_gain):
        raise ValueError(f"finger {finger}: the calibration holds "
                         f"{len(cal.electrode_gain)} fingertip(s)")
    gain = np.asarray(cal.electrode_gain[finger])
    residual = np.asarray(cal.electrode_residual)
    load = rise / max(float(rise.max()), 1.0)
    shear = colored_noise(rng, gain.size, n, 0.5 / _FRAME_S).T * residual[None, :]
    electrodes = (np.asarray(cal.rest_electrodes)
                  + rng.normal(0.0, 1.0, gain.size) * np.asarray(cal.rest_electrodes_spread)
                  + np.outer(t, rng.normal(0.0, cal.drift_electrodes_per_s, gain.size))
                  + np.outer(rise * np.where(weights > 0, weights, 1.0), gain)
                  + shear * load[:, None]
                  + rng.normal(0.0, 1.0, (n, gain.size)) * np.asarray(cal.noise_electrodes))

    samples = n * _N_PAC
    pac = cal.rest_pac + _shaped_pac_noise(rng, samples, np.asarray(cal.pac_band_rms))
    dpdc = np.abs(np.diff(pdc, prepend=pdc[0]))
    rest_std = float(np.sqrt(np.sum(np.asarray(cal.pac_band_rms) ** 2)))
    vibration = np.clip(cal.pac_press_base + cal.pac_press_gain * dpdc - rest_std, 0.0, None)
    pac = pac + np.repeat(vibration, _N_PAC) * rng.standard_normal(samples)
    tac = cal.rest_tac + rng.normal(0.0, cal.noise_tac, n)
    tdc = cal.rest_tdc + rng.normal(0.0, cal.noise_tdc, n)

    def counts(values: FloatArray) -> FloatArray:
        return np.clip(np.round(values), 0.0, 4095.0)

    return BioTacFrames(layout_for("biotac"), t, counts(pac).reshape(n, _N_PAC), counts(pdc),
                        counts(tac), counts(tdc), counts(electrodes))
