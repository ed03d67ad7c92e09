"""Config of the ``dynamixel`` robot (import-light: pydantic only)."""

from __future__ import annotations

import math
from typing import Annotated, Any, Literal

from pydantic import BaseModel, ConfigDict, Field, model_validator

from hapticframe import PluginConfig, RegionConfig
from hapticframe.devices import FaultKind, FaultKinds, FaultParam, FaultValue

__all__ = [
    "FAULT_KINDS",
    "AxisConfig",
    "DynamixelRobotConfig",
    "GantryConfig",
    "JointConfig",
    "KinematicsConfig",
    "TwoLinkConfig",
]

#: The emulator's own fault kinds (hapticframe_dynamixel._emulator.FAULT_KINDS describes
#: them); the harness adds the byte-level ones. ``validate`` refuses any other kind and
#: parameter.
_SERVO = {"id": FaultParam(0, 252, integer=True)}
FAULT_KINDS: dict[str, FaultKind] = {
    "no_reply": FaultKind("one status packet is not sent", _SERVO),
    "bad_crc": FaultKind("one status packet with a corrupted CRC", _SERVO),
    "error_code": FaultKind("one status packet carries ERR params.error",
                            {**_SERVO, "error": FaultParam(1, 7, integer=True)}),
    "late_reply": FaultKind("one status packet params.delay_s late",
                            {**_SERVO, "delay_s": FaultParam(0.0, 60.0)}),
    "late_duplicate": FaultKind("one status packet sent again before the next", _SERVO),
    "junk": FaultKind("params.count random bytes (params.half=1: half a packet) before one "
                      "status packet", {**_SERVO, "count": FaultParam(1, 4096, integer=True),
                                        "half": FaultParam(0, 1, integer=True)}),
    "stuffing": FaultKind("the shaft found at the multi-turn position params.position",
                          {**_SERVO, "position": FaultParam(-(2**31), 2**31 - 1, integer=True)}),
    "sync_missing": FaultKind("one servo leaves one SYNC_READ unanswered", _SERVO),
    "hardware_error": FaultKind("Hardware Error Status bit params.bit latched",
                                {**_SERVO, "bit": FaultParam(0, 7, integer=True)}),
    "current_spike": FaultKind("Present Current raised by params.amps for duration_s",
                               {**_SERVO, "amps": FaultParam(-100.0, 100.0)}),
    "power_loss": FaultKind("a servo loses its supply for an instant", _SERVO),
}

class AxisConfig(BaseModel):
    """One gantry axis: a servo driving a lead screw or a pulley.

    The axis coordinate is ``offset_m + metres_per_rad * angle``, the angle being the
    servo's position in radians (4096 pulses per turn, pulse 0 = 0 rad).
    """

    model_config = ConfigDict(frozen=True, extra="forbid", allow_inf_nan=False)

    id: int = Field(ge=0, le=252, description="The servo's Dynamixel ID.")
    metres_per_rad: float = Field(
        gt=0, le=1.0,
        description="Travel per radian of the shaft (lead / 2π, or the pulley radius)."
    )
    offset_m: float = Field(0.0, ge=-10.0, le=10.0, description="The axis coordinate at pulse 0.")
    min_pulse: int = Field(0, ge=0, le=4095, description="Min Position Limit (pulses).")
    max_pulse: int = Field(4095, ge=0, le=4095, description="Max Position Limit (pulses).")

    @model_validator(mode="after")
    def _ordered(self) -> AxisConfig:
        if self.max_pulse <= self.min_pulse:
            raise ValueError("max_pulse must exceed min_pulse")
        return self


class GantryConfig(BaseModel):
    """A Cartesian gantry: x and y in the map plane, z vertical (depth = −z)."""

    model_config = ConfigDict(frozen=True, extra="forbid", allow_inf_nan=False)

    type: Literal["gantry"] = "gantry"
    x: AxisConfig = AxisConfig(id=1, metres_per_rad=0.125)
    y: AxisConfig = AxisConfig(id=2, metres_per_rad=0.125)
    z: AxisConfig = AxisConfig(id=3, metres_per_rad=0.01, offset_m=-0.06)

    @model_validator(mode="after")
    def _distinct(self) -> GantryConfig:
        ids = [self.x.id, self.y.id, self.z.id]
        if len(set(ids)) != 3:
            raise ValueError(f"the gantry's servo IDs must be distinct, got {ids}")
        return self


class JointConfig(BaseModel):
    """A revolute joint of the two-link arm: a servo, directly or through a reduction.

    The joint angle is ``offset_rad + angle / gear_ratio``, the angle being the servo's
    position in radians (4096 pulses per turn, pulse 0 = 0 rad). The servos run in position
    mode (one turn): the joint's range is at most 360° / |gear_ratio|.
    """

    model_config = ConfigDict(frozen=True, extra="forbid", allow_inf_nan=False)

    id: int = Field(ge=0, le=252, description="The servo's Dynamixel ID.")
    gear_ratio: float = Field(
        1.0, description="Servo turns per joint turn (a reduction, |ratio| ≥ 1); negative: "
        "the joint turns against the servo.")
    offset_rad: float = Field(0.0, ge=-10.0, le=10.0, description="The joint angle at pulse 0.")
    min_pulse: int = Field(0, ge=0, le=4095, description="Min Position Limit (pulses).")
    max_pulse: int = Field(4095, ge=0, le=4095, description="Max Position Limit (pulses).")

    @model_validator(mode="after")
    def _sane(self) -> JointConfig:
        if self.max_pulse <= self.min_pulse:
            raise ValueError("max_pulse must exceed min_pulse")
        if not (math.isfinite(self.gear_ratio) and 1.0 <= abs(self.gear_ratio) <= 1000.0):
            raise ValueError(f"gear_ratio must be a reduction with 1 ≤ |gear_ratio| ≤ 1000 "
                             f"(negative to reverse the joint), got {self.gear_ratio}")
        if not math.isfinite(self.offset_rad):
            raise ValueError("offset_rad must be finite")
        return self


class TwoLinkConfig(BaseModel):
    """A planar shoulder-elbow arm in the map plane on a vertical z axis (depth = −z).

    The shoulder's axis stands at ``base_m``; the upper arm (``l1_m``) turns with the
    shoulder servo from the map's x axis, the forearm (``l2_m``) with the elbow servo
    relative to the upper arm, both counter-clockwise seen from above. The default covers
    the default workspace (0...0.75 m × 0...0.5 m) from a shoulder 0.1 m below its edge,
    each joint through a 2:1 reduction (a joint range of 180°, 0.77 mrad per pulse).
    """

    model_config = ConfigDict(frozen=True, extra="forbid", allow_inf_nan=False)

    type: Literal["two-link"]
    l1_m: float = Field(0.4, gt=0, le=5.0, description="Shoulder-to-elbow length.")
    l2_m: float = Field(0.4, gt=0, le=5.0, description="Elbow-to-fingertip length.")
    base_m: tuple[float, float] = Field(
        (0.375, -0.1), description="The shoulder axis's position (x, y) in the map frame.")
    elbow_side: Literal["left", "right"] = Field(
        "right", description="The inverse kinematics' branch: the elbow to the right or the "
        "left of the line from the shoulder to the fingertip, seen from above (right: the "
        "elbow joint's angle is positive).")
    shoulder: JointConfig = JointConfig(id=1, gear_ratio=2.0, offset_rad=-1.06)
    elbow: JointConfig = JointConfig(id=2, gear_ratio=2.0, offset_rad=0.35)
    z: AxisConfig = AxisConfig(id=3, metres_per_rad=0.01, offset_m=-0.06)

    @model_validator(mode="after")
    def _sane(self) -> TwoLinkConfig:
        ids = [self.shoulder.id, self.elbow.id, self.z.id]
        if len(set(ids)) != 3:
            raise ValueError(f"the arm's servo IDs must be distinct, got {ids}")
        if not all(math.isfinite(v) for v in (self.l1_m, self.l2_m, *self.base_m)):
            raise ValueError("l1_m, l2_m and base_m must be finite")
        return self


KinematicsConfig = Annotated[GantryConfig | TwoLinkConfig, Field(discriminator="type")]


class DynamixelRobotConfig(PluginConfig):
    """A chain of Dynamixel XM430-W350 servos (Protocol 2.0) moving the fingertip: a
    Cartesian gantry or a planar two-link arm, each on a vertical depth axis.

    ``port: emulated`` runs the servos on an emulated bus behind a pseudo-terminal that the
    unmodified ``dynamixel_sdk`` opens, in simulation time (deterministic).
    """

    port: str = Field(
        "emulated", description="The serial device (e.g. /dev/ttyUSB0), or 'emulated'."
    )
    baudrate: int = Field(1_000_000, gt=0, le=10_000_000, description="Bus baud rate.")
    control_rate_hz: float = Field(50.0, gt=0, le=1000, description="Control steps per second.")
    kinematics: KinematicsConfig = Field(
        default_factory=GantryConfig, description="The mechanism: type 'gantry' (default, a "
        "Cartesian gantry) or 'two-link' (a planar arm on a vertical axis)."
    )
    workspace: RegionConfig = Field(
        default_factory=RegionConfig,
        description="The rectangle (x_min_m, x_max_m, y_min_m, y_max_m) the fingertip may "
        "rake; the mechanism must reach all of it at depth_m, and the robot refuses a "
        "movement that leaves it.",
    )
    depth_m: float = Field(
        0.044, gt=0, le=1.0, description="Raking depth for movements that do not give one."
    )
    transit_speed_m_per_s: float = Field(
        0.1, gt=0, le=2.0,
        description="Speed of the move to a movement's start (no states recorded)."
    )
    tolerance_m: float = Field(
        0.001, gt=0, le=0.1,
        description="A movement ends once the measured fingertip is this close "
        "to its end (and the commanded point is there)."
    )
    settle_steps: int = Field(
        100, ge=1, le=100_000,
        description="At most this many control steps past the commanded end to "
        "settle within tolerance_m (then halt_reason 'not_settled')."
    )
    max_retries: int = Field(
        3, ge=0, le=100, description="Retries of a failed bus transaction before a recovery."
    )
    max_recoveries: int = Field(
        3, ge=1, le=100, description="Failed recoveries in a row before DeviceError."
    )
    reply_timeout_ms: float = Field(
        500.0, gt=0, le=60_000,
        description="Emulator only: the SDK's reply timeout (real time). The "
        "emulated servos answer at once in simulation time, so only an injected missing reply "
        "waits this long; a short one lets a loaded machine's delay pass for a lost reply, and "
        "the retries it causes change the run."
    )
    # -- emulator (port: emulated) -----------------------------------------------------------
    time_constant_s: float = Field(
        0.05, gt=0, le=60.0, description="Emulator: first-order lag of each servo behind its goal."
    )
    emulated_ids: tuple[int, ...] | None = Field(
        None, description="Emulator: the servo IDs on the emulated bus (default: the "
        "kinematics' IDs; leave one out to emulate a missing servo)."
    )
    faults: Annotated[FaultValue, FaultKinds(FAULT_KINDS)] = Field(
        "none",
        description="Emulator only: 'none', 'standard' (rare status faults), or a list of "
        "fault events ({kind, at_s | rate_hz, duration_s, params}) of DynamixelBus.",
    )

    @model_validator(mode="before")
    @classmethod
    def _gantry_by_default(cls, data: Any) -> Any:
        # A kinematics mapping without a type is the gantry (as before the two-link arm).
        if isinstance(data, dict):
            kinematics = data.get("kinematics")
            if isinstance(kinematics, dict) and "type" not in kinematics:
                data = {**data, "kinematics": {**kinematics, "type": "gantry"}}
        return data

    @model_validator(mode="after")
    def _consistent(self) -> DynamixelRobotConfig:
        if self.faults != "none" and not self.emulated:
            raise ValueError("faults are injected by the emulator: they need port 'emulated'")
        return self

    @property
    def emulated(self) -> bool:
        """Whether ``port`` names the emulator."""
        return self.port == "emulated"
