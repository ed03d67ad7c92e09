"""Synthetic BioTac trials of a fingertip raked through granular media past a buried cylinder.

Reproduces the experiment of dissertation chapter 2 (§2.6): a fingertip swept at constant
commanded speed, 5 cm deep, through one of the five media of Table 2.1, over a 9.1 cm
cylinder whose top lies 4 cm deep. Every effect is tied to an observation of §2.8 and every
assumption is listed in ``docs/synthetic-biotac.md``. Pure numpy, float64, seeded generators.

Map frame: x along the rake (metres), y lateral, origin above the cylinder's axis in the
nominal placement; the axis is parallel to y at ``x = object_offset_m``.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, cast

import numpy as np
from numpy.typing import NDArray

from ._synthetic_media import (
    MEDIA,
    REFERENCE_DIAMETER_M,
    REFERENCE_SPEED_M_PER_S,
    MediumName,
    colored_noise,
    contact_pattern,
    drag_pattern,
    highpass_fft,
    nominal_sensor_baselines,
    pulse_train,
    sawtooth_events,
)

__all__ = [
    "CYLINDER_DIAMETER_M",
    "CYLINDER_TOP_DEPTH_M",
    "FRAME_PERIOD_S",
    "PAC_PER_FRAME",
    "Trial",
    "TrialSpec",
    "contact_interval_x_m",
    "frame_features",
    "generate_open_air_trial",
    "generate_trial",
    "granular_noise_ratios",
    "open_air_frames",
    "robustness_specs",
    "training_specs",
]

FloatArray = NDArray[np.float64]

FRAME_PERIOD_S = 0.01
PAC_PER_FRAME = 22
PAC_RATE_HZ = PAC_PER_FRAME / FRAME_PERIOD_S
N_ELECTRODES = 19
COUNT_MAX = 4095.0
CYLINDER_DIAMETER_M = 0.091
CYLINDER_TOP_DEPTH_M = 0.04
_RADIUS_M = CYLINDER_DIAMETER_M / 2.0
# Rake path: 12.5 cm, starting 4-5 cm before the nominal axis, so that both the nominal and
# the +3.5 cm object leave free movement before first and after last contact.
PATH_LENGTH_M = 0.125
_PATH_START_M = (-0.050, -0.040)
SPEED_RANGE_M_PER_S = (0.005, 0.2)
_MEDIA_NAMES = cast("tuple[MediumName, ...]", tuple(MEDIA))

# Sensor noise at rest (open air), counts (1σ).
_AIR_SIGMA = {"pac": 1.6, "pdc": 1.5, "tac": 1.2, "tdc": 1.0, "electrodes": 1.5}
# Granular-media amplitudes at the reference condition (cottonwood, 4 cm/s, 5 cm), counts.
# They are calibrated so that the IQR ratios of thesis §2.8.1.1 come out (see the docs).
_PAC_FRICTION_SIGMA = 8.0
_PAC_IMPACT_RMS = 45.0
_PDC_DRAG = 60.0
_SLOW_FLUCTUATION_REL = 0.50
_ELECTRODE_DRAG = 20.0
_ELECTRODE_LOCAL_SIGMA = 6.0
# Electrode #7 (tip centre) sees least granular noise and #11 most (IQR ×5, ×3 and ×6 for
# #1, #7 and #11, §2.8.1.1); the others follow from the drag pattern and the local noise.
_ELECTRODE_EXPOSURE = np.ones(N_ELECTRODES)
_ELECTRODE_EXPOSURE[0] = 1.2
_ELECTRODE_EXPOSURE[6] = 0.33
_ELECTRODE_EXPOSURE[10] = 1.45
# Object contact, counts per unit load.
_ELECTRODE_CONTACT = 130.0
_PDC_CONTACT = 70.0
_JAM_GAIN = 0.6
_JAM_LENGTH_M = 0.0016  # 40 ms at 4 cm/s for 20 mm beads (§2.8.1.3)
_ONSET_INTERFERENCE_M = 0.004
_RELEASE_INTERFERENCE_M = 0.0003
_FORCE_CHAIN_RATE_HZ = 0.6
_FORCE_CHAIN_MEAN_LOAD = 0.25
_PAC_TRANSIENT = 60.0
_PDC_TRANSIENT = 25.0
_THERMAL_DROP = 40.0
# Time to lower the fingertip from its open-air tare pose into the media (assumption).
_LOWERING_S = 1.0


@dataclass(frozen=True)
class TrialSpec:
    """Conditions of one trial (thesis §2.6.2-2.6.3)."""

    medium: MediumName
    speed_m_per_s: float
    orientation_deg: float
    object_offset_m: float
    has_object: bool
    fingertip_depth_m: float = 0.05

    def validate(self) -> None:
        """Raise ``ValueError`` for a medium or value the generator does not model."""
        if self.medium not in MEDIA:
            raise ValueError(f"unknown medium {self.medium!r}; expected one of {_MEDIA_NAMES}")
        checks = (
            ("speed_m_per_s", self.speed_m_per_s, *SPEED_RANGE_M_PER_S),
            ("orientation_deg", self.orientation_deg, -45.0, 45.0),
            ("object_offset_m", self.object_offset_m, -0.05, 0.05),
            ("fingertip_depth_m", self.fingertip_depth_m, 0.01, 0.12),
        )
        for name, value, low, high in checks:
            if not np.isfinite(value) or not low <= value <= high:
                raise ValueError(f"{name}={value!r} outside the modelled range [{low}, {high}]")


@dataclass(frozen=True)
class Trial:
    """One synthetic trial: a 100 Hz frame per row, counts as 12-bit values in float64.

    ``extras`` (not part of equality) holds ground truth beyond the shared layout: the digit
    (``"a"`` or ``"b"``), the fingertip depth per frame, the first/last contact frames and
    ``air_rest``, the noise-free counts at rest in open air before the trial (see
    :func:`open_air_frames`).
    """

    spec: TrialSpec
    timestamps_s: FloatArray
    pac: FloatArray
    pdc: FloatArray
    tac: FloatArray
    tdc: FloatArray
    electrodes: FloatArray
    position_m: FloatArray
    contact: NDArray[np.int8]
    extras: dict[str, Any] = field(default_factory=dict, compare=False, repr=False)

    @property
    def n_frames(self) -> int:
        """Number of 10 ms frames."""
        return int(self.timestamps_s.shape[0])


def contact_interval_x_m(
    spec: TrialSpec, depth_m: float | None = None
) -> tuple[float, float] | None:
    """Fingertip x of first and last contact for a straight rake at ``depth_m``.

    Returns ``None`` when there is no object or the fingertip passes above it. The chord is
    about 5.7 cm at 5 cm depth (the thesis measured about 5.4 cm, §2.7.3).
    """
    depth = spec.fingertip_depth_m if depth_m is None else depth_m
    interference = depth - CYLINDER_TOP_DEPTH_M
    if not spec.has_object or interference <= 0.0:
        return None
    half = float(np.sqrt(max(_RADIUS_M**2 - (_RADIUS_M - min(interference, _RADIUS_M)) ** 2, 0.0)))
    return spec.object_offset_m - half, spec.object_offset_m + half


def _kinematics(spec: TrialSpec, rng: np.random.Generator, n: int) -> tuple[FloatArray, ...]:
    """Fingertip x, y and depth per frame: position control with small tracking errors."""
    t = np.arange(n, dtype=np.float64) * FRAME_PERIOD_S
    speed_gain = 1.0 + float(np.clip(rng.normal(0.0, 0.02), -0.05, 0.05))
    x0 = rng.uniform(*_PATH_START_M)
    wander = colored_noise(rng, 3, n, 0.2 / FRAME_PERIOD_S)
    x = x0 + spec.speed_m_per_s * speed_gain * t + 0.0003 * wander[0]
    y = rng.normal(0.0, 0.001) + 0.0002 * wander[1]
    # The rake ran at most 1 cm below the cylinder's top (thesis §2.8.1.2): depth only errs upward.
    depth_offset = -min(abs(rng.normal(0.0, 0.002)), 0.005)
    depth = spec.fingertip_depth_m + depth_offset + 0.0003 * wander[2]
    return t, x, y + np.zeros(n), depth


def _contact_load(
    spec: TrialSpec, x: FloatArray, depth: FloatArray, jam_length_m: float
) -> tuple[NDArray[np.int8], FloatArray, FloatArray, int | None, int | None]:
    """Label and normalised object load per frame from the geometry (thesis §2.6.2, §2.8.1.3).

    Returns ``(contact, load, jam, first, last)``; the load rises with the fingerpad's
    interference on the way in and drops within a fraction of a millimetre at the slip-off.
    """
    n = x.shape[0]
    contact = np.zeros(n, dtype=np.int8)
    load = np.zeros(n)
    jam = np.zeros(n)
    if not spec.has_object:
        return contact, load, jam, None, None
    centre_depth = CYLINDER_TOP_DEPTH_M + _RADIUS_M
    interference = _RADIUS_M - np.hypot(x - spec.object_offset_m, depth - centre_depth)
    inside = np.flatnonzero(interference > 0.0)
    if inside.size == 0:
        return contact, load, jam, None, None
    first, last = int(inside[0]), int(inside[-1])
    contact[first : last + 1] = 1
    pen = np.clip(interference, 0.0, None)
    approach = x < spec.object_offset_m
    scale = np.where(approach, _ONSET_INTERFERENCE_M, _RELEASE_INTERFERENCE_M)
    load = 1.0 - np.exp(-pen / scale)
    before = np.arange(n) < first
    gap = np.clip(x[first] - x, 0.0, None)
    jam[before] = _JAM_GAIN * np.exp(-gap[before] / jam_length_m)
    return contact, load, jam, first, last


def _synthesize(spec: TrialSpec, rng: np.random.Generator, granular: bool) -> Trial:
    """Build one trial; ``granular=False`` leaves out every effect of the media."""
    spec.validate()
    medium = MEDIA[spec.medium]
    v = spec.speed_m_per_s
    size_rel = medium.diameter_m / REFERENCE_DIAMETER_M
    speed_rel = v / REFERENCE_SPEED_M_PER_S
    n = int(PATH_LENGTH_M / (v * FRAME_PERIOD_S)) + 1
    g = 1.0 if granular else 0.0

    # --- inter-trial state: digit, baselines, gains, packing, contact firmness ---------------
    base = nominal_sensor_baselines()
    digit = "a" if spec.has_object else ("a" if rng.random() < 0.5 else "b")
    electrodes_base = (
        base[f"electrodes_{digit}"] + rng.normal(0.0, 60.0, N_ELECTRODES) + rng.normal(0.0, 40.0)
    )
    pdc0, tac0, tdc0, pac0 = base[f"scalars_{digit}"] + rng.normal(0.0, [40.0, 10.0, 80.0, 4.0])
    gain = rng.lognormal(0.0, 0.1)
    electrode_gain = gain * rng.lognormal(0.0, 0.12, N_ELECTRODES)
    packing = rng.lognormal(0.0, 0.15)
    firmness = rng.lognormal(0.0, 0.3)

    t, x, y, depth = _kinematics(spec, rng, n)
    jam_length = _JAM_LENGTH_M * np.sqrt(size_rel)
    contact, load, jam, first, last = _contact_load(spec, x, depth, jam_length)
    # Particles caught between the skin and the cylinder make the sliding load stick and slip;
    # the bigger the particles, the larger the swings (25 % for cottonwood beads).
    slip = colored_noise(rng, 1, n, 0.05 / FRAME_PERIOD_S)[0]
    slip_rel = 0.03 + g * 0.22 * np.sqrt(size_rel)
    object_load = firmness * (load * np.clip(1.0 + slip_rel * slip, 0.0, None) + g * jam)

    # --- granular drag (pdc and pad electrodes) and force chains -----------------------------
    drag_rel = (
        medium.particle_density_kg_m3 / MEDIA["cottonwood_beads"].particle_density_kg_m3
        * (depth.mean() / 0.05) ** 2 * (0.5 + medium.friction) / 0.95
    )
    tau_slow = float(np.clip(0.5 * medium.diameter_m / v, 0.01, 1.0)) / FRAME_PERIOD_S
    fluct_rel = _SLOW_FLUCTUATION_REL * np.sqrt(size_rel) * speed_rel**0.3
    drag = drag_rel * packing * (1.0 + fluct_rel * colored_noise(rng, 1, n, tau_slow)[0])
    sqrt_size = np.sqrt(size_rel)
    chain_load, chain_release = sawtooth_events(
        rng, n, FRAME_PERIOD_S, _FORCE_CHAIN_RATE_HZ * speed_rel * sqrt_size,
        _FORCE_CHAIN_MEAN_LOAD * sqrt_size, (0.05 * sqrt_size + 0.03, 0.35 * sqrt_size + 0.05),
    )
    tip_load = object_load + g * chain_load

    # --- after last contact: the fingertip is flung into the media (§2.8.1.2) ----------------
    release = np.zeros(n)
    pac_time = np.arange(n * PAC_PER_FRAME) / PAC_RATE_HZ
    pac_burst = np.zeros_like(pac_time)
    if last is not None and last + 1 < n:
        onset = t[last] + FRAME_PERIOD_S + rng.uniform(0.0, 0.02)
        lag = t - onset
        release = np.where(lag > 0.0, (lag / 0.04) * np.exp(1.0 - lag / 0.04), 0.0)
        lag_pac = pac_time - onset
        ring_hz = rng.uniform(90.0, 130.0)
        envelope = np.where(lag_pac > 0.0, np.exp(-lag_pac / 0.04), 0.0)
        pac_burst = envelope * np.sin(2.0 * np.pi * ring_hz * np.clip(lag_pac, 0.0, None))
        pac_burst *= _PAC_TRANSIENT * firmness * (1.0 if granular else 0.3) * speed_rel**0.5

    # --- pdc ---------------------------------------------------------------------------------
    pdc_drift = rng.normal(0.0, 1.0)
    pdc = (
        pdc0 + pdc_drift * t
        + gain * (g * _PDC_DRAG * drag + _PDC_CONTACT * tip_load)
        + gain * g * _PDC_TRANSIENT * firmness * release
        + rng.normal(0.0, _AIR_SIGMA["pdc"], n)
    )

    # --- electrodes --------------------------------------------------------------------------
    # Where the object presses on the tip follows the cylinder's surface normal (frame by
    # frame; the compliant finger turns with it, so the load moves by 60 % of the tilt) and
    # the fingertip's roll on its mount (trial by trial).
    centre_depth = CYLINDER_TOP_DEPTH_M + _RADIUS_M
    surface = 0.6 * np.rad2deg(np.arctan2(x - spec.object_offset_m, centre_depth - depth))
    if first is not None:
        surface[:first] = surface[first]
    roll = rng.normal(0.0, 8.0)
    object_pattern = contact_pattern(spec.orientation_deg, surface, roll)
    chain_pattern = contact_pattern(spec.orientation_deg, -20.0, roll)
    local_tau = float(np.clip(0.25 * medium.diameter_m / v, 0.01, 0.5)) / FRAME_PERIOD_S
    local_sigma = _ELECTRODE_LOCAL_SIGMA * sqrt_size * speed_rel**0.3 * np.sqrt(drag_rel)
    local = colored_noise(rng, N_ELECTRODES, n, local_tau)
    local *= (local_sigma * _ELECTRODE_EXPOSURE)[:, None]
    deformation = (
        g * _ELECTRODE_DRAG * np.outer(drag_pattern(spec.orientation_deg), drag)
        + _ELECTRODE_CONTACT * (object_pattern * object_load[:, None]).T
        + g * _ELECTRODE_CONTACT * np.outer(chain_pattern, chain_load)
        + g * local
    )
    drift = rng.normal(0.0, 0.7) + rng.normal(0.0, 0.4, N_ELECTRODES)
    electrodes = (
        electrodes_base[:, None] + np.outer(drift, t) + electrode_gain[:, None] * deformation
        + rng.normal(0.0, _AIR_SIGMA["electrodes"], (N_ELECTRODES, n))
    ).T

    # --- temperature: the warm fingertip loses heat to the media and to the plastic object --
    entered_s = rng.uniform(2.0, 10.0)  # how long before frame 0 the finger entered the media
    since_entry = t + entered_s
    heat_loss = (0.3 + 0.7 * g * medium.thermal_effusivity_rel) * _THERMAL_DROP
    heat_loss *= rng.lognormal(0.0, 0.2)
    cooling = heat_loss * (1.0 - np.exp(-since_entry / 10.0))
    cooling += 0.5 * np.cumsum(load) * FRAME_PERIOD_S
    tdc = tdc0 - cooling + rng.normal(0.0, _AIR_SIGMA["tdc"], n)
    cooling_rate = np.gradient(cooling, FRAME_PERIOD_S) if n > 1 else np.zeros(n)
    tac = tac0 - 4.0 * cooling_rate + rng.normal(0.0, _AIR_SIGMA["tac"], n)

    # --- pac: particle impacts, sliding friction, slips of force chains, release burst ------
    pac = _pac_signal(spec, rng, n, contact_fraction=np.repeat(load, PAC_PER_FRAME),
                      chain_release=chain_release, release=release, granular=granular,
                      drag_rel=drag_rel * packing)
    pac = pac0 + gain * (pac + pac_burst) + rng.normal(0.0, _AIR_SIGMA["pac"], pac.shape)

    def counts(values: FloatArray) -> FloatArray:
        return np.clip(np.round(values), 0.0, COUNT_MAX)

    return Trial(
        spec=spec,
        timestamps_s=t,
        pac=counts(pac).reshape(n, PAC_PER_FRAME),
        pdc=counts(pdc),
        tac=counts(tac),
        tdc=counts(tdc),
        electrodes=counts(electrodes),
        position_m=np.column_stack([x, y]),
        contact=contact,
        extras={
            "digit": digit, "depth_m": depth, "first_contact": first, "last_contact": last,
            # The noise-free counts at rest in open air just before the finger was lowered
            # into the media (the drifts run back to then; no load, no cooling yet).
            "air_rest": {
                "pac": float(pac0),
                "pdc": float(pdc0 - pdc_drift * (entered_s + _LOWERING_S)),
                "tac": float(tac0),
                "tdc": float(tdc0),
                "electrodes": electrodes_base - drift * (entered_s + _LOWERING_S),
            },
        },
    )


def _hertz_contact_s(diameter_m: float, mass_kg: float, speed: float) -> float:
    """Hertzian impact duration of a particle on the silicone skin (E* ≈ 1 MPa, R_f = 7 mm)."""
    radius = 1.0 / (2.0 / diameter_m + 1.0 / 0.007)
    return 2.87 * (mass_kg**2 / (radius * 1.0e6**2 * speed)) ** 0.2


def _pac_signal(
    spec: TrialSpec,
    rng: np.random.Generator,
    n: int,
    contact_fraction: FloatArray,
    chain_release: FloatArray,
    release: FloatArray,
    granular: bool,
    drag_rel: float,
) -> FloatArray:
    """Granular part of pac before baseline and sensor noise (counts)."""
    total = n * PAC_PER_FRAME
    if not granular:
        return np.zeros(total)
    medium = MEDIA[spec.medium]
    v = spec.speed_m_per_s
    speed_rel = v / REFERENCE_SPEED_M_PER_S
    pulse_s = _hertz_contact_s(medium.diameter_m, medium.particle_mass_kg, v)
    pulse_hz = 0.5 / pulse_s
    antialias = 1.0 / np.sqrt(1.0 + (pulse_hz / 1000.0) ** 2)
    # Particles displaced per second by a 3 cm² frontal area, three skin contacts each.
    rate = v * 3.0e-4 * 0.6 / (np.pi * medium.diameter_m**3 / 6.0) * 3.0
    cap = 4000.0
    reference = MEDIA["cottonwood_beads"]
    # Impact energy ∝ m v², so the total impact power ∝ rate m v² ∝ ρ v³ (size-free).
    amplitude = (
        _PAC_IMPACT_RMS * np.sqrt(medium.particle_mass_kg / reference.particle_mass_kg) * speed_rel
        * np.sqrt(max(rate / cap, 1.0)) * antialias
    )
    frame_rate = np.repeat(1.0 + 6.0 * release, PAC_PER_FRAME) * min(rate, cap)
    frame_rate = frame_rate * (1.0 - 0.2 * contact_fraction)
    impacts = pulse_train(rng, total, PAC_RATE_HZ, frame_rate, amplitude, pulse_s)
    tau = PAC_RATE_HZ / (2.0 * np.pi * pulse_hz)
    friction_sigma = (
        _PAC_FRICTION_SIGMA * speed_rel * np.sqrt(medium.friction / reference.friction * drag_rel)
        * antialias
    )
    friction = friction_sigma * colored_noise(rng, 1, total, tau)[0]
    # A collapsing force chain lets go like one big impact.
    slips = np.zeros(total)
    slips[::PAC_PER_FRAME] = chain_release * 4.0 * _PAC_IMPACT_RMS * rng.choice([-1.0, 1.0], n)
    slip_pulse = np.sin(np.pi * (np.arange(8) + 0.5) / 8)
    slips = np.convolve(slips, slip_pulse)[:total]
    return highpass_fft(impacts + friction + slips, 10.0, PAC_RATE_HZ)


def generate_trial(spec: TrialSpec, rng: np.random.Generator) -> Trial:
    """One seeded trial through granular media (see the module docstring for the frame).

    Raises
    ------
    ValueError
        For a medium, speed, orientation, offset or depth outside the modelled range.
    """
    return _synthesize(spec, rng, granular=True)


def generate_open_air_trial(spec: TrialSpec, rng: np.random.Generator) -> Trial:
    """The same rake with the media removed (the thesis's open-air "ground truth" trials).

    The medium only names the condition; no drag, particle noise, jamming or force chains act.
    """
    return _synthesize(spec, rng, granular=False)


def open_air_frames(trial: Trial, n_frames: int, rng: np.random.Generator) -> dict[str, FloatArray]:
    """``n_frames`` frames of the trial's fingertip at rest in open air, before the trial.

    BioTac users zero the sensor in air before lowering it into the media; these are the
    frames such a tare averages: the trial's resting counts just before the finger entered
    the media (``trial.extras["air_rest"]``) plus the sensor's noise at rest, as 12-bit
    counts. Returns ``pac`` (n, 22), ``pdc``, ``tac``, ``tdc`` (n,) and ``electrodes``
    (n, 19). Draws from ``rng`` only, so the trial itself is unchanged.

    Raises
    ------
    ValueError
        If ``n_frames`` < 1 or the trial carries no open-air resting counts.
    """
    if int(n_frames) < 1:
        raise ValueError(f"n_frames must be at least 1, got {n_frames!r}")
    rest = trial.extras.get("air_rest")
    if not isinstance(rest, dict):
        raise ValueError("the trial carries no open-air resting counts (extras['air_rest'])")
    n = int(n_frames)
    shapes = {"pac": (n, PAC_PER_FRAME), "pdc": (n,), "tac": (n,), "tdc": (n,),
              "electrodes": (n, N_ELECTRODES)}
    out = {}
    for name, shape in shapes.items():
        level = np.broadcast_to(np.asarray(rest[name], dtype=np.float64), shape[1:])
        values = level + rng.normal(0.0, _AIR_SIGMA[name], shape)
        out[name] = np.clip(np.round(values), 0.0, COUNT_MAX)
    return out


def training_specs(rng: np.random.Generator) -> list[TrialSpec]:
    """The 750 training trials of §2.6.2: cottonwood, 4 cm/s, 250 with contact, 500 without."""
    specs = [TrialSpec("cottonwood_beads", 0.04, 0.0, 0.0, True)] * 250
    specs += [TrialSpec("cottonwood_beads", 0.04, 0.0, 0.0, False)] * 500
    return [specs[i] for i in rng.permutation(len(specs))]


def robustness_specs(rng: np.random.Generator) -> list[TrialSpec]:
    """The robustness set of §2.6.3: per medium 50 trials with contact and 25 without, at 2 cm/s.

    Fingertip orientation (0° or 20°) and object placement (0 or +3.5 cm) are balanced and
    shuffled across the trials of each medium.
    """
    specs: list[TrialSpec] = []
    for medium in _MEDIA_NAMES:
        for has_object, count in ((True, 50), (False, 25)):
            orientation = rng.permutation(np.resize([0.0, 20.0], count))
            offset = rng.permutation(np.resize([0.0, 0.035], count))
            specs += [
                TrialSpec(medium, 0.02, float(o), float(d) if has_object else 0.0, has_object)
                for o, d in zip(orientation, offset, strict=True)
            ]
    return specs


def frame_features(trial: Trial) -> FloatArray:
    """Raw per-frame features: pac(22), pdc, tac, tdc, electrodes(19) side by side, (n, 44)."""
    return np.column_stack([trial.pac, trial.pdc, trial.tac, trial.tdc, trial.electrodes])


def _iqr(values: FloatArray) -> float:
    q1, q3 = np.percentile(values, [25.0, 75.0])
    return float(q3 - q1)


def granular_noise_ratios(
    spec: TrialSpec, rng: np.random.Generator, n_trials: int = 20
) -> dict[str, float]:
    """Median within-trial IQR in granular media over the same in open air (thesis §2.8.1.1).

    Uses free-movement frames of trials without the object. Keys: ``pac`` (all 22 samples per
    frame), ``pdc``, ``electrode_1``, ``electrode_7``, ``electrode_11`` and ``electrodes``
    (the median over all 19).
    """
    if n_trials < 1:
        raise ValueError("n_trials must be at least 1")
    free = TrialSpec(spec.medium, spec.speed_m_per_s, spec.orientation_deg, 0.0, False,
                     spec.fingertip_depth_m)
    sums: dict[str, list[list[float]]] = {"granular": [], "air": []}
    for kind, make in (("granular", generate_trial), ("air", generate_open_air_trial)):
        for _ in range(n_trials):
            tr = make(free, rng)
            sums[kind].append(
                [_iqr(tr.pac.ravel()), _iqr(tr.pdc)]
                + [_iqr(tr.electrodes[:, e]) for e in range(N_ELECTRODES)]
            )
    granular = np.median(np.array(sums["granular"]), axis=0)
    air = np.maximum(np.median(np.array(sums["air"]), axis=0), 1.0)  # IQR of integer counts
    ratio = granular / air
    return {
        "pac": float(ratio[0]),
        "pdc": float(ratio[1]),
        "electrode_1": float(ratio[2]),
        "electrode_7": float(ratio[8]),
        "electrode_11": float(ratio[12]),
        "electrodes": float(np.median(ratio[2:])),
    }

