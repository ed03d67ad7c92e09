"""Config models of the simulated sandbox robot and its force sensor (import-light)."""

from __future__ import annotations

from pydantic import Field, field_validator, model_validator

from hapticframe import PluginConfig, RegionConfig

__all__ = ["SandboxForceSensorConfig", "SandboxRobotConfig", "SandboxTaxelSensorConfig"]


class SandboxRobotConfig(PluginConfig):
    """A rigid plate raked vertically through a simulated sand mixture.

    Defaults follow the thesis's real-robot experiment (section 3.5.3): 4.4 cm depth, vertical
    raking (α = 90°), an 80 N force limit, and the depth schedule of section 3.5.1.
    """

    control_rate_hz: float = Field(100.0, gt=0, le=10_000, description="Control steps per second.")
    depth_m: float = Field(
        0.044, gt=0, le=0.3,
        description="Initial raking depth below the free surface.",
    )
    depth_reduction_m: float = Field(
        0.01,
        ge=0,
        le=0.3,
        description="Depth lost after the first exploratory movement that reaches the object "
        "(displaced soil); later reductions shrink by depth_reduction_ratio.",
    )
    depth_reduction_ratio: float = Field(
        0.5, ge=0, le=1, description="Factor between successive depth reductions (1, 0.5, 0.25 cm)."
    )
    min_depth_m: float = Field(
        0.005, gt=0, le=0.3,
        description="The depth schedule never goes below this.",
    )
    rake_angle_deg: float = Field(
        90.0, gt=0, lt=180, description="Plate angle α to the free surface (90 = vertical)."
    )
    shear_band_angle_deg: float | None = Field(
        None,
        gt=0,
        lt=90,
        description="Shear-band angle β; None takes the scene material's Arthur angle.",
    )
    side_crescent_angle_deg: float | None = Field(
        None,
        gt=0,
        le=90,
        description="Failure-zone half-angle η; None uses (50 + 7n)° with n the number of "
        "completed pairs of object interactions (Table 3.1), capped at 90°.",
    )
    plate_width_m: float = Field(0.02, gt=0, le=1.0, description="Width of the fingertip plate.")
    drag_coefficient_n_per_m2: float = Field(
        7750.0,
        ge=0,
        le=1e6,
        description="Free plate drag F = c d²; 7750 gives about 15 N at 4.4 cm (Figure 3.6).",
    )
    shear_cycle_length_fraction: float = Field(
        0.5,
        gt=0,
        le=10, description="Mean length of one shear-band nucleation cycle, as a fraction of the "
        "rupture distance.",
    )
    shear_cycle_amplitude: float = Field(
        0.2,
        ge=0,
        lt=1,
        description="Mean peak-to-peak drag swing of a cycle, relative to the drag.",
    )
    shear_cycle_jitter: float = Field(
        0.25,
        ge=0,
        lt=1,
        description="Relative spread (uniform ±) of each cycle's length and amplitude.",
    )
    drag_fluctuation_fraction: float = Field(
        0.03, ge=0, le=1,
        description="Std of the slow random drag fluctuation, relative to the drag."
    )
    drag_fluctuation_time_s: float = Field(
        0.3, gt=0, le=100, description="Correlation time of that fluctuation."
    )
    jamming_gain_n_per_m: float = Field(
        1200.0,
        ge=0,
        le=1e6, description="Jamming surge when the plate reaches the object, per metre of depth "
        "(1200 gives about 53 N at 4.4 cm).",
    )
    jamming_exponent: float = Field(
        1.5, gt=0, le=10,
        description="Shape p of the surge g d ((r − s)/r)^p as the plate approaches."
    )
    contact_stiffness_n_per_m: float = Field(
        3000.0, ge=0, le=1e7,
        description="Force per metre pushed into an object after direct contact."
    )
    force_limit_n: float = Field(
        80.0, gt=0, le=10_000, description="The robot halts itself above this true force magnitude."
    )
    sector_radial_samples: int = Field(
        40, ge=2, le=1000, description="Samples per ray when locating objects in the failure zone."
    )
    sector_angular_samples: int = Field(
        21, ge=1, le=1001, description="Rays across the failure zone (odd keeps one on the axis)."
    )
    # The tool's inertia and the wrist sensor, for the physical truth that drives emulated
    # force/torque sensors and IMUs (docs/simulated-devices.md).
    end_effector_mass_kg: float = Field(
        0.8, gt=0, le=100,
        description="Mass beyond the wrist force/torque sensor (plate and mount)."
    )
    acceleration_m_per_s2: float | None = Field(
        None,
        ge=1e-3,
        le=100,
        description="Acceleration at the start and deceleration at the end of each movement "
        "(a trapezoidal speed profile; at least 1 mm/s², a ramp of 50 s to 5 cm/s); None "
        "starts and stops at once (constant speed). validate also checks that the longest "
        "line ends within run.max_steps_per_movement.",
    )
    sensor_height_m: float = Field(
        0.1,
        ge=0,
        le=2.0,
        description="Height of the wrist sensor's origin above the fingertip: the lever arm "
        "of the environment force's torque.",
    )
    workspace: RegionConfig | None = Field(
        None,
        description="The rectangle the fingertip can reach (x_min_m, x_max_m, y_min_m, "
        "y_max_m); None reaches everywhere. The robot refuses a line that leaves it; a run "
        "rakes a movement that leaves it up to the boundary (workspace_limit) and continues "
        "it with another robot whose workspace holds the rest, and refuses one that starts "
        "where no workspace reaches (outside_workspace).",
    )

    follows: str | None = Field(
        None,
        description="The id of an emulated robot (also named in inputs) whose fingertip the "
        "sandbox follows instead of moving a plate of its own: the sandbox computes the sand's "
        "force around that robot's measured fingertip, which drives emulated sensors (inputs "
        "naming this sandbox) and loads the robot's emulated actuators. The robot's open "
        "depths come from the sandbox's depth schedule. None: the sandbox moves on its own.",
    )

    @model_validator(mode="after")
    def _depths_consistent(self) -> SandboxRobotConfig:
        if self.min_depth_m > self.depth_m:
            raise ValueError("min_depth_m must not exceed depth_m")
        return self


class SandboxForceSensorConfig(PluginConfig):
    """A 2-D force sensor on the simulated fingertip: the true force plus white noise."""

    noise_std_n: float = Field(
        0.3, ge=0, le=1000, description="Standard deviation of the noise added to each force axis."
    )


Twelve = tuple[float, float, float, float, float, float, float, float, float, float, float, float]

# Fitted by hapticframe_raking.calibrate_sandbox_taxels() (80 real training trials against
# sandbox approaches; seed 7): docs/benchmarks.md, "Search with the distance estimate".
_FIT_OFFSET: Twelve = (0.0432, 0.8043, 0.3962, 0.0952, 0.1712, 0.3446, 0.2681, 0.3013, 0.3683,
                      0.251, 0.8314, 0.3515)
_FIT_ALONG: Twelve = (0.0136, -0.0039, -0.0023, 0.0121, 0.0094, 0.0029, 0.0147, 0.0108, 0.0053,
                     0.0093, -0.0056, 0.0074)
_FIT_ACROSS: Twelve = (-0.0172, 0.0007, 0.0053, -0.0076, -0.0181, -0.0053, -0.0202, -0.021,
                      -0.0063, -0.0123, 0.0029, -0.0098)
_FIT_NOISE: Twelve = (0.0172, 0.0117, 0.0652, 0.0251, 0.0124, 0.0546, 0.0195, 0.0175, 0.0358,
                     0.0174, 0.0254, 0.0318)

class SandboxTaxelSensorConfig(PluginConfig):
    """The sandbox force as 4 taxels x 3 axes (normalized), by a declared linear model.

    Each of the twelve numbers of a field is one channel, taxel-major (taxel 1 x, y, z,
    taxel 2 x, y, z, ...), as the real data set orders them.
    """

    offset: Twelve = Field(_FIT_OFFSET, description="Reading at zero force, per channel.")
    gain_along_per_n: Twelve = Field(
        _FIT_ALONG, description="Reading per newton of force against the motion.")
    gain_across_per_n: Twelve = Field(
        _FIT_ACROSS, description="Reading per newton of force to the left of the motion.")
    noise_std: Twelve = Field(_FIT_NOISE, description="Standard deviation of each "
                              "channel's white noise (what the force does not explain).")
    direction_split_deg: float = Field(
        10.0, gt=0, lt=180, allow_inf_nan=False, description="Label: the nearest object "
        "point more than this clockwise of the heading is class 0, counter-clockwise 2.")
    deep_m: float = Field(0.03, gt=0, le=1, allow_inf_nan=False,
                          description="Label: raking at least this deep is depth class 0.")
    approach_trials: int = Field(
        0, ge=0, le=100_000, description="Above 0: a training source that drives its robot "
        "through this many approaches at the scene's objects, one recording each.")
    approach_standoff_m: float = Field(0.15, gt=0, le=10, allow_inf_nan=False,
                                       description="Free travel before each approach.")

    @field_validator("offset", "gain_along_per_n", "gain_across_per_n", "noise_std")
    @classmethod
    def _finite(cls, value: Twelve) -> Twelve:
        if not all(abs(v) < 1e6 for v in value):
            raise ValueError("every number must be finite and below 1e6 in size")
        return value

    @field_validator("noise_std")
    @classmethod
    def _non_negative(cls, value: Twelve) -> Twelve:
        if any(v < 0 for v in value):
            raise ValueError("noise standard deviations must not be negative")
        return value
