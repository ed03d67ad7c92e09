"""Config of the ``barrett-wam`` robot (import-light: pydantic only)."""

from __future__ import annotations

import math
from typing import Annotated, Literal

from pydantic import BaseModel, ConfigDict, Field, model_validator

from hapticframe import PluginConfig, RegionConfig
from hapticframe.devices import FaultKinds, FaultValue

from ._hand_config import PUCK_FAULT_KINDS

__all__ = ["BarrettWamConfig", "DHRow"]


class DHRow(BaseModel):
    """One standard Denavit-Hartenberg row (libbarrett's ``moving`` entries)."""

    model_config = ConfigDict(frozen=True, extra="forbid", allow_inf_nan=False)

    a_m: float = Field(ge=-10.0, le=10.0, description="Link length a.")
    alpha_rad: float = Field(ge=-7.0, le=7.0, description="Link twist α.")
    d_m: float = Field(ge=-10.0, le=10.0, description="Link offset d.")
    theta_offset_rad: float = Field(0.0, ge=-7.0, le=7.0, description="Added to the joint angle θ.")


class BarrettWamConfig(PluginConfig):
    """A Barrett WAM (4-DOF by default, or 7-DOF) moving the fingertip along straight lines at
    trajectory level: joint positions read from the pucks, joint targets (``M``) sent to pucks
    that the safety system holds in PID. The robot never sets ``MODE`` on the arm.

    ``channel: emulated`` runs the pucks on python-can's ``virtual`` interface in simulation
    time (deterministic). The kinematic fields left empty take the arm's published values
    (libbarrett's ``wam4.conf`` / ``wam7w.conf``; see ``_wam_kinematics``).
    """

    channel: str = Field(
        "emulated", description="The python-can channel (e.g. can0), or 'emulated'."
    )
    interface: str = Field("socketcan", description="The python-can interface of a real bus.")
    control_rate_hz: float = Field(100.0, gt=0, le=500, description="Control steps per second.")
    arm: Literal["wam4", "wam7"] = Field("wam4", description="Which WAM (its published model).")
    dh: tuple[DHRow, ...] | None = Field(
        None, description="The DH table (default: the arm's, from libbarrett)."
    )
    j2mp: tuple[tuple[float, ...], ...] | None = Field(
        None, description="Joint-to-motor matrix (motor rad = j2mp @ joint rad; default: the "
        "arm's)."
    )
    joint_limits_rad: tuple[tuple[float, float], ...] | None = Field(
        None, description="(low, high) of each joint (default: Barrett's published ranges)."
    )
    tool_offset_m: tuple[float, float, float] | None = Field(
        None, description="The fingertip in the last joint's frame (default: wam4 0.36 m "
        "toolplate + 0.15 m finger along the forearm; wam7 0.2 m past the wrist)."
    )
    tool_axis: tuple[float, float, float] | None = Field(
        None, description="The tool direction (last joint's frame) the IK prefers pointing "
        "down (a preference: 4 joints cannot hold it with the position; default: the "
        "toolplate's z)."
    )
    pointing_gain: float = Field(0.5, ge=0, le=100.0, description="Weight of that preference.")
    base_position_m: tuple[float, float, float] = Field(
        (0.375, -0.25, 0.30), description="The arm's base frame (shoulder) in the map frame; "
        "z is the height above the free surface."
    )
    base_yaw_rad: float = Field(
        0.5 * math.pi, ge=-7.0, le=7.0,
        description="The base frame's rotation about the map's z axis."
    )
    ik_seed_rad: tuple[float, ...] | None = Field(
        None, description="The posture IK starts from when the present one fails (default: "
        "elbow up, over the default workspace)."
    )
    workspace: RegionConfig = Field(
        default_factory=RegionConfig,
        description="The reachable rectangle; the robot refuses a movement that leaves it.",
    )
    depth_m: float = Field(
        0.044, gt=0, le=1.0,
        description="Raking depth for movements without one.",
    )
    transit_speed_m_per_s: float = Field(
        0.1, gt=0, le=2.0,
        description="Speed of the move to a movement's start (no states recorded)."
    )
    transit_height_m: float = Field(
        0.05, ge=0, le=1.0,
        description="Transits lift the fingertip this far above the free surface."
    )
    min_link_height_m: float = Field(
        0.05, ge=-1.0, le=2.0,
        description="Every joint origin (elbow, wrist) stays this far above the surface."
    )
    max_joint_speed_rad_per_s: float = Field(
        1.0, gt=0, le=10.0,
        description="A movement needing a faster joint is refused (singularities)."
    )
    ik_step_m: float = Field(
        0.004, gt=0, le=0.05, description="Spacing of the IK solutions along a line (joint "
        "targets in between are interpolated)."
    )
    ik_tolerance_m: float = Field(1e-5, gt=0, le=0.01, description="IK position tolerance.")
    tolerance_m: float = Field(
        0.001, gt=0, le=0.1,
        description="A movement ends once the measured fingertip is this close "
        "to its end (and the commanded point is there)."
    )
    settle_steps: int = Field(
        50, ge=1, le=100_000,
        description="At most this many steps past the commanded end to settle "
        "(then halt_reason 'not_settled')."
    )
    following_error_rad: float = Field(
        0.05, gt=0, le=3.2,
        description="A joint this far from its target for following_steps steps "
        "in a row means the arm is not following (an E-stop, a collision): DeviceError."
    )
    following_steps: int = Field(5, ge=1, le=10_000, description="See following_error_rad.")
    mode_check_every: int = Field(
        1, ge=0, le=10_000,
        description="Read one puck's MODE every this many steps, in turn (0: never; "
        "an E-stop is then found by the following error)."
    )
    reply_timeout_s: float = Field(0.05, gt=0, le=10.0, description="Bound on a property reply.")
    position_timeout_s: float = Field(
        0.004, gt=0, le=1.0, description="Bound on a group position poll's replies."
    )
    attempts: int = Field(2, ge=1, le=100, description="Requests per property read.")
    max_retries: int = Field(
        3, ge=0, le=100, description="Position polls repeated in a step before a recovery."
    )
    max_recoveries: int = Field(
        3, ge=1, le=100,
        description="Failed recoveries in a row: DeviceError.",
    )
    recovery_backoff_s: float = Field(
        0.05, ge=0, le=60.0,
        description="The first recovery's wait; each next one doubles (max 1 s)."
    )
    wake_time_s: float = Field(
        1.0, gt=0, le=60.0,
        description="Wait after STAT=READY (libbarrett: 1 s).",
    )
    torque_control: bool = Field(
        False, description="EXPERIMENTAL, not implemented: packed-torque control. Must be false."
    )
    # -- emulator (channel: emulated) -----------------------------------------------------------
    emulated_vers: int = Field(
        160, ge=65, le=65_535,
        description="Emulator: the pucks' firmware VERS.",
    )
    emulated_speed_counts_per_s: float = Field(
        40_000.0, gt=0, le=1e7, description="Emulator: how fast a puck follows its target."
    )
    emulated_start_rad: tuple[float, ...] | None = Field(
        None, description="Emulator: the posture at power-on (default: the fingertip over the "
        "workspace's centre at the transit height)."
    )
    emulated_operator_activates: bool = Field(
        True, description="Emulator: the operator presses Shift-Activate when the robot "
        "activates (false: the pucks stay IDLE and activation fails)."
    )
    faults: Annotated[FaultValue, FaultKinds(PUCK_FAULT_KINDS, byte_faults=False)] = Field(
        "none", description="Emulator only: 'none', 'standard' (rare puck faults), or a list "
        "of fault events ({kind, at_s | rate_hz, duration_s, params}) of PuckBus."
    )

    @model_validator(mode="after")
    def _consistent(self) -> BarrettWamConfig:
        if self.torque_control:
            raise ValueError(
                "torque_control is experimental and not implemented: the barrett-wam robot "
                "sends joint position targets only (packed torques stay out); set it false"
            )
        if self.faults != "none" and not self.emulated:
            raise ValueError("faults are injected by the emulator: they need channel 'emulated'")
        n = 4 if self.arm == "wam4" else 7
        for name in ("dh", "j2mp", "joint_limits_rad", "ik_seed_rad", "emulated_start_rad"):
            value = getattr(self, name)
            if value is not None and len(value) != n:
                raise ValueError(f"{name} needs {n} rows for arm {self.arm!r}, got {len(value)}")
        if self.j2mp is not None and any(len(row) != n for row in self.j2mp):
            raise ValueError(f"j2mp must be {n}×{n}")
        return self

    @property
    def emulated(self) -> bool:
        """Whether ``channel`` names the emulator."""
        return self.channel == "emulated"
