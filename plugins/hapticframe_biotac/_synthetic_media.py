"""Granular media, fingertip layout and noise primitives of the synthetic BioTac generator.

Everything here is pure numpy and float64, and every random draw comes from a
``numpy.random.Generator`` passed in. The physical reasoning behind each number is in
``docs/synthetic-biotac.md``; the comments below only say where a value comes from.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np
from numpy.typing import NDArray

__all__ = [
    "ELECTRODE_XYZ_MM",
    "MEDIA",
    "MediumName",
    "MediumProperties",
    "colored_noise",
    "contact_pattern",
    "drag_pattern",
    "highpass_fft",
    "nominal_sensor_baselines",
    "pulse_train",
    "sawtooth_events",
]

FloatArray = NDArray[np.float64]
MediumName = Literal["poppy_seed", "plastic_pellets", "bbs", "pine_beads", "cottonwood_beads"]

#: Particle diameter of the training medium (cottonwood beads, thesis §2.6.2); the scaling
#: laws below are written relative to it so that the training condition is the reference.
REFERENCE_DIAMETER_M = 0.020
REFERENCE_SPEED_M_PER_S = 0.04


@dataclass(frozen=True)
class MediumProperties:
    """One granular medium of thesis Table 2.1.

    Attributes
    ----------
    diameter_m
        Particle diameter (Table 2.1).
    particle_density_kg_m3
        Density of one particle (assumed from the material, not given in the thesis).
    friction
        Particle-skin friction coefficient (assumed: wood rough, airsoft BBs smooth).
    thermal_effusivity_rel
        Heat drawn from the warm fingertip relative to cottonwood (assumed; drives tdc/tac).
    """

    diameter_m: float
    particle_density_kg_m3: float
    friction: float
    thermal_effusivity_rel: float

    @property
    def particle_mass_kg(self) -> float:
        """Mass of one spherical particle."""
        return self.particle_density_kg_m3 * np.pi * self.diameter_m**3 / 6.0


MEDIA: dict[str, MediumProperties] = {
    "poppy_seed": MediumProperties(0.001, 1100.0, 0.50, 1.6),
    "plastic_pellets": MediumProperties(0.003, 950.0, 0.35, 1.3),
    "bbs": MediumProperties(0.006, 1100.0, 0.20, 1.3),
    "pine_beads": MediumProperties(0.016, 500.0, 0.45, 1.0),
    "cottonwood_beads": MediumProperties(0.020, 420.0, 0.45, 1.0),
}

# Electrode centres of the 19-electrode BioTac in its own frame (mm): x toward the distal tip,
# y lateral, z normal (negative = fingerpad side). Values as tabulated in the SynTouch manual;
# #1, #7 and #11 sit at the fingertip as thesis Figure 2.9 says.
ELECTRODE_XYZ_MM: FloatArray = np.array(
    [
        [0.993, -4.855, -1.116],
        [-2.700, -3.513, -3.670],
        [-6.200, -3.513, -3.670],
        [-8.000, -4.956, -1.116],
        [-10.500, -3.513, -3.670],
        [-13.400, -4.956, -1.116],
        [4.763, 0.000, -2.330],
        [3.031, -1.950, -3.330],
        [3.031, 1.950, -3.330],
        [1.299, 0.000, -4.330],
        [0.993, 4.855, -1.116],
        [-2.700, 3.513, -3.670],
        [-6.200, 3.513, -3.670],
        [-8.000, 4.956, -1.116],
        [-10.500, 3.513, -3.670],
        [-13.400, 4.956, -1.116],
        [-2.800, 0.000, -5.080],
        [-9.800, 0.000, -5.080],
        [-13.600, 0.000, -5.080],
    ],
    dtype=np.float64,
)

# Distal fingertip modelled as a sphere around the origin; the object touches it at an angle
# from the finger axis toward the pad (25° puts the load on electrode #7 in the nominal pose).
_TIP_RADIUS_MM = 5.5
_NOMINAL_CONTACT_ANGLE_DEG = 25.0
# Skin mechanics: compression under the load (Gaussian, σ in mm) and a bulge ring around it.
_COMPRESSION_SIGMA_MM = 2.5
_BULGE_RADIUS_MM = 6.5
_BULGE_SIGMA_MM = 1.8
_BULGE_GAIN = 0.55


def contact_pattern(
    orientation_deg: float, surface_angle_deg: FloatArray | float = 0.0, roll_deg: float = 0.0
) -> FloatArray:
    """Per-electrode response to a unit load on the distal tip.

    Positive entries are compressed electrodes (impedance up, #7 in the nominal pose), negative
    ones bulge (#1 and #11), as thesis §2.8.1.2 describes. A fingertip extended by
    ``orientation_deg`` meets the object further toward the pad, so the load moves from #7
    toward #8-#10.

    Parameters
    ----------
    orientation_deg
        Extension of the fingertip relative to the training pose (0° or 20° in the thesis).
    surface_angle_deg
        Tilt of the object's surface normal at the contact from vertical, positive when the
        object lies behind the fingertip (scalar or one value per frame). On the way up the
        cylinder the load sits on the pad side, at the top on the tip, on the way down past it.
    roll_deg
        Rotation of the fingertip about its own axis (mounting tolerance), which moves the load
        toward electrode #1 or #11.

    Returns
    -------
    (19,) float64 for a scalar angle, else (len(surface_angle_deg), 19); the largest entry
    is about 1.
    """
    tilt = np.asarray(surface_angle_deg, dtype=np.float64)
    angle = np.deg2rad(_NOMINAL_CONTACT_ANGLE_DEG + float(orientation_deg) - tilt)
    roll = np.deg2rad(float(roll_deg))
    radial = _TIP_RADIUS_MM * np.sin(angle)
    points = np.stack(
        [_TIP_RADIUS_MM * np.cos(angle), radial * np.sin(roll), -radial * np.cos(roll)],
        axis=-1,
    )
    distance = np.linalg.norm(ELECTRODE_XYZ_MM - points[..., None, :], axis=-1)
    compression = np.exp(-0.5 * (distance / _COMPRESSION_SIGMA_MM) ** 2)
    bulge = _BULGE_GAIN * np.exp(-0.5 * ((distance - _BULGE_RADIUS_MM) / _BULGE_SIGMA_MM) ** 2)
    return compression - bulge


def drag_pattern(orientation_deg: float) -> FloatArray:
    """Per-electrode response to granular drag spread over the leading fingerpad.

    The pad (most negative z) carries the drag; the side electrodes feel little. Extending the
    finger turns more of the pad into the flow, which raises the whole pattern slightly.
    """
    z = ELECTRODE_XYZ_MM[:, 2]
    pad = np.exp(-0.5 * ((z + 5.08) / 2.0) ** 2)
    return pad * (1.0 + 0.5 * np.sin(np.deg2rad(float(orientation_deg))))


def nominal_sensor_baselines() -> dict[str, FloatArray]:
    """Resting 12-bit counts of the two fingertips (digits) of the thesis's set-up.

    Each BioTac has its own electrode offsets; raw resting electrode counts lie between about
    2,300 and 3,400 (perception notes §3.3: the MIT BioTac SP set has a median of 2,824).
    The pattern is fixed (drawn once from a constant seed) so that every trial of one digit
    shares it.
    """
    rng = np.random.default_rng(20220615)
    return {
        "electrodes_a": rng.uniform(2350.0, 3350.0, size=19),
        "electrodes_b": rng.uniform(2350.0, 3350.0, size=19),
        "scalars_a": np.array([2050.0, 2040.0, 2580.0, 2048.0]),  # pdc, tac, tdc, pac centre
        "scalars_b": np.array([1910.0, 2065.0, 2470.0, 2036.0]),
    }


def colored_noise(rng: np.random.Generator, rows: int, n: int, tau_samples: float) -> FloatArray:
    """Unit-variance first-order (Ornstein-Uhlenbeck) noise, one independent row each.

    Filtering white noise by the exponential kernel in the frequency domain keeps this free
    of Python loops; a burn-in of five correlation times makes the start stationary.

    Parameters
    ----------
    tau_samples
        Correlation time in samples; values below 0.5 give white noise.
    """
    if n <= 0 or rows <= 0:
        return np.zeros((max(rows, 0), max(n, 0)))
    if tau_samples < 0.5:
        return rng.standard_normal((rows, n))
    phi = float(np.exp(-1.0 / tau_samples))
    burn = int(min(5.0 * tau_samples, 20.0 * n)) + 1
    total = n + burn
    white = rng.standard_normal((rows, total))
    kernel = np.sqrt(1.0 - phi**2) * phi ** np.arange(total, dtype=np.float64)
    size = 1 << int(np.ceil(np.log2(2 * total)))
    spectrum = np.fft.rfft(white, size, axis=1) * np.fft.rfft(kernel, size)[None, :]
    filtered = np.fft.irfft(spectrum, size, axis=1)[:, :total]
    return filtered[:, burn:]


def highpass_fft(signal: FloatArray, cutoff_hz: float, sample_rate_hz: float) -> FloatArray:
    """First-order high-pass (the AC coupling of the BioTac's pac channel), zero start state.

    Applied as the analog response ``jf/fc / (1 + jf/fc)`` on a zero-padded FFT so that the
    tail does not wrap around onto the start.
    """
    n = signal.shape[-1]
    if n == 0:
        return signal.copy()
    size = 1 << int(np.ceil(np.log2(2 * n)))
    freqs = np.fft.rfftfreq(size, d=1.0 / sample_rate_hz)
    ratio = 1j * freqs / cutoff_hz
    spectrum = np.fft.rfft(signal, size, axis=-1) * (ratio / (1.0 + ratio))
    return np.fft.irfft(spectrum, size, axis=-1)[..., :n]


def pulse_train(
    rng: np.random.Generator,
    n: int,
    sample_rate_hz: float,
    rate_hz: FloatArray | float,
    amplitude: float,
    pulse_s: float,
) -> FloatArray:
    """Particle impacts on the skin: Poisson events convolved with a half-sine pressure pulse.

    Parameters
    ----------
    rate_hz
        Event rate, a scalar or one value per sample (so bursts can be added).
    amplitude
        Root-mean-square impulse size; each event draws a log-normal factor around it.
    pulse_s
        Hertzian contact duration; pulses shorter than one sample become one sample.

    Returns
    -------
    (n,) float64
    """
    rate = np.broadcast_to(np.asarray(rate_hz, dtype=np.float64), (n,))
    counts = rng.poisson(np.clip(rate, 0.0, None) / sample_rate_hz)
    total = int(counts.sum())
    train = np.zeros(n)
    if total:
        where = np.repeat(np.arange(n), counts)
        # Log-normal sizes (σ = 0.6) scaled to unit mean square; random sign of the first lobe.
        sizes = rng.lognormal(-0.36, 0.6, total) * rng.choice([-1.0, 1.0], total)
        # A weighted bincount is float64 already (numpy's stub says intp): astype copies nothing.
        summed = np.bincount(where, weights=sizes * amplitude, minlength=n)
        train = summed.astype(np.float64, copy=False)
    length = max(1, round(pulse_s * sample_rate_hz))
    pulse = np.sin(np.pi * (np.arange(length) + 0.5) / length)
    pulse /= np.sqrt(np.sum(pulse**2))
    return np.convolve(train, pulse)[:n]


def sawtooth_events(
    rng: np.random.Generator,
    n: int,
    frame_s: float,
    rate_hz: float,
    mean_amplitude: float,
    build_range_s: tuple[float, float],
) -> tuple[FloatArray, FloatArray]:
    """Force-chain jams during free movement: a load that builds up and collapses at once.

    Returns
    -------
    load : (n,) float64
        Sum of the ramps (each from 0 to its amplitude over its build time).
    collapse : (n,) float64
        The amplitude released at each frame (for the slip burst in pac).
    """
    load = np.zeros(n)
    collapse = np.zeros(n)
    count = int(rng.poisson(max(rate_hz, 0.0) * n * frame_s))
    if count == 0 or n < 2:
        return load, collapse
    ends = rng.integers(1, n, size=count)
    builds = rng.uniform(*build_range_s, size=count) / frame_s
    amplitudes = rng.exponential(mean_amplitude, size=count)
    frames = np.arange(n, dtype=np.float64)
    for end, build, amplitude in zip(ends, builds, amplitudes, strict=True):
        ramp = 1.0 - (end - frames) / max(build, 1.0)
        ramp[(frames > end) | (ramp < 0.0)] = 0.0
        load += amplitude * ramp
        if end + 1 < n:
            collapse[end + 1] += amplitude
    return load, collapse
