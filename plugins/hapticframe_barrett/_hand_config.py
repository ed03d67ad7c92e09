"""Config of the ``barrett-hand`` robot (import-light: pydantic only).

Finger geometry and joint conversions
-------------------------------------
Defaults are the BarrettHand BH8 series' published values:

- link lengths: the flexion (inner) joint's link ``proximal_m`` = 0.070 m (OpenRAVE's
  ``barretthand.kinbody.xml``, the 0.07 m between a finger's inner and outer joints; the
  BH8-series manual's A2) and the fingertip link ``distal_m`` = 0.050 m (the manual's A3;
  unverified against a hand);
- the outer joint is coupled to the inner one: ``outer = inner / 3 + 50°`` while the finger
  moves freely (OpenRAVE's ``mimic="JF1 0.33333 0.8727"``; libbarrett's ``J2_RATIO /
  J3_RATIO`` = 125 / 375);
- encoder counts per radian of a joint: ``CTS / 2π`` of the puck's motor times the
  reduction, 125 for a finger's inner joint and 17.5 for the spread (libbarrett
  ``hand.h``: ``J2_RATIO``, ``SPREAD_RATIO``; ``hand.cpp``: ``j2pp = countsPerRad *
  J2_RATIO``). ``CTS`` is read from each puck (4096 on the hand's pucks).

Joint angles are measured as libbarrett does: 0 is a finger opened flat in the palm's plane,
closing turns it toward the palm's normal (90°: the inner link points straight out of the
palm) and on over the palm (140°, the limit).
"""

from __future__ import annotations

import math
from typing import Annotated, Literal

from pydantic import BaseModel, ConfigDict, Field, model_validator

from hapticframe import PluginConfig
from hapticframe.devices import FaultKind, FaultKinds, FaultParam, FaultValue

__all__ = ["PUCK_FAULT_KINDS", "BarrettHandRobotConfig", "FingerGeometryConfig"]

#: The emulated CAN bus's fault kinds (hapticframe_barrett._emulator.FAULT_KINDS); no byte
#: harness sits in front of a CAN bus. ``validate`` refuses any other kind and parameter.
_NODE = {"node": FaultParam(1, 31, integer=True)}
PUCK_FAULT_KINDS: dict[str, FaultKind] = {
    "never_wakes": FaultKind("a puck (params.node) never wakes; params.absent=1: not on the bus",
                             {**_NODE, "absent": FaultParam(0, 1, integer=True)}),
    "late_reply": FaultKind("one reply params.delay_s late",
                            {**_NODE, "delay_s": FaultParam(0.0, 60.0)}),
    "malformed_reply": FaultKind("one reply malformed as params.how", {
        **_NODE, "how": FaultParam(choices=("bit7", "byte1", "short", "wrong_property"))}),
    "duplicate_reply": FaultKind("one reply sent params.count more times",
                                 {"count": FaultParam(1, 1000, integer=True)}),
    "missing_position": FaultKind("one puck's position missing from a group read", _NODE),
    "estop": FaultKind("the E-stop is pressed"),
    "error_frame": FaultKind("params.count CAN error frames",
                             {"count": FaultParam(1, 1000, integer=True)}),
    "bus_off": FaultKind("the CAN controller goes bus-off"),
}
#: Inner-joint angle at which the default fingertip link points straight down (the
#: dissertation's "vertical orientation"): inner + inner / 3 + 50° = 90°, i.e. 30°.
VERTICAL_TIP_RAD = math.radians(30.0)


class FingerGeometryConfig(BaseModel):
    """A finger's two links and the coupling of its outer joint to its inner joint."""

    model_config = ConfigDict(frozen=True, extra="forbid", allow_inf_nan=False)

    proximal_m: float = Field(
        0.070, gt=0, le=1.0, description="Inner (proximal) link: inner joint to outer joint."
    )
    distal_m: float = Field(
        0.050, gt=0, le=1.0, description="Outer (distal) link: outer joint to the fingertip."
    )
    coupling: float = Field(
        1.0 / 3.0, ge=0, le=10.0, description="Outer-joint angle per radian of the inner joint "
        "(J2_RATIO / J3_RATIO)."
    )
    distal_offset_rad: float = Field(
        0.8727, ge=-7.0, le=7.0, description="Outer-joint angle at inner angle 0 (50°)."
    )
    inner_ratio: float = Field(
        125.0, gt=0, le=10_000, description="Motor turns per turn of the inner joint (J2_RATIO)."
    )
    spread_ratio: float = Field(
        17.5, gt=0, le=10_000, description="Motor turns per turn of the spread (SPREAD_RATIO)."
    )


class BarrettHandRobotConfig(PluginConfig):
    """A BarrettHand (pucks 11-14 on CAN) holding a raking posture on a carrier robot.

    Two fingers are flexed toward the palm and one is extended (the dissertation's rig); the
    carrier robot (the one robot in ``inputs``) moves the hand along each line. The
    fingertip is the extended finger's tip: its depth below the carrier's tool point is
    ``palm_below_tool_point_m`` plus the finger's reach below the palm at the posture.
    ``channel: emulated`` runs the pucks on python-can's ``virtual`` interface in
    simulation time (deterministic).
    """

    channel: str = Field(
        "emulated", description="The CAN channel (e.g. can0), or 'emulated'."
    )
    interface: str = Field(
        "socketcan", description="python-can interface of a real channel (e.g. socketcan, "
        "pcan, kvaser)."
    )
    bitrate: int = Field(
        1_000_000, gt=0, le=10_000_000,
        description="CAN bit rate (the pucks use 1 Mbit/s).",
    )
    raking_finger: Literal[1, 2, 3] = Field(
        3, description="The finger left extended for raking (3: the finger the spread does "
        "not move); the other two are flexed."
    )
    raking_angle_rad: float = Field(
        VERTICAL_TIP_RAD, ge=0, le=math.radians(140),
        description="Inner-joint angle of the raking finger (default 30°: its fingertip "
        "link vertical, palm down).",
    )
    flexed_angle_rad: float = Field(
        math.radians(120), ge=0, le=math.radians(140),
        description="Inner-joint angle of the two flexed fingers.",
    )
    spread_rad: float = Field(
        0.0, ge=0, le=math.pi, description="Spread angle of the posture."
    )
    finger: FingerGeometryConfig = Field(
        default_factory=FingerGeometryConfig,
        description="Finger link lengths, the outer joint's coupling, the joint reductions.",
    )
    palm_below_tool_point_m: float = Field(
        0.0, ge=-1.0, le=1.0,
        description="How far the palm lies below the carrier's tool point (negative: the "
        "carrier's kinematic model puts its tool point below the palm).",
    )
    depth_m: float | None = Field(
        None, gt=0, le=1.0, description="Fingertip depth of a movement that gives none (None: the "
        "carrier keeps its own depth and the fingertip is that much deeper).",
    )
    initialize: bool = Field(
        True, description="Home the hand (CMD HI, fingers then spread) on activate."
    )
    hold: bool = Field(
        True, description="Set HOLD so that the pucks hold the posture in PID (an E-stop, "
        "MODE forced to IDLE, is then seen)."
    )
    posture_tolerance_rad: float = Field(
        0.02, gt=0, le=3.2,
        description="Each joint within this of its target after the posture move."
    )
    displacement_tolerance_rad: float = Field(
        0.08, gt=0, le=3.2, description="A joint pushed further than this from its target while "
        "raking stops the carrier (DeviceError)."
    )
    poll_every_steps: int = Field(
        5, ge=1, le=10_000, description="Poll the hand's positions and MODE every this many steps."
    )
    max_missing_polls: int = Field(
        3, ge=1, le=10_000,
        description="Polls in a row without a puck's position before DeviceError."
    )
    move_timeout_s: float = Field(
        10.0, gt=0, le=600.0, description="Bound on homing and on the posture move."
    )
    reply_timeout_s: float = Field(
        0.1, gt=0, le=10.0, description="Bound on each property reply (libbarrett waits 1 s)."
    )
    attempts: int = Field(2, ge=1, le=100, description="Requests per property read.")
    max_recoveries: int = Field(
        3, ge=1, le=100, description="Failed recoveries in a row before DeviceError."
    )
    recovery_backoff_s: float = Field(
        0.1, gt=0, le=60.0,
        description="The first recovery waits this long, each next twice as long."
    )
    # -- emulator (channel: emulated) --------------------------------------------------------
    emulated_vers: int = Field(
        160, ge=65, le=65_535,
        description="Emulator: the pucks' firmware VERS.",
    )
    emulated_speed: float = Field(
        50_000.0, gt=0, le=1e7, description="Emulator: joint speed in encoder counts per second."
    )
    emulated_nodes: tuple[int, ...] | None = Field(
        None, description="Emulator: the pucks on the bus (default 11-14; leave one out "
        "to emulate a missing puck)."
    )
    faults: Annotated[FaultValue, FaultKinds(PUCK_FAULT_KINDS, byte_faults=False)] = Field(
        "none",
        description="Emulator only: 'none', 'standard' (rare reply faults and error frames), "
        "or a list of PuckBus fault events ({kind, at_s | rate_hz, duration_s, params}).",
    )

    @model_validator(mode="after")
    def _consistent(self) -> BarrettHandRobotConfig:
        if self.faults != "none" and not self.emulated:
            raise ValueError("faults are injected by the emulator: they need channel "
                             "'emulated'")
        return self

    @property
    def emulated(self) -> bool:
        """Whether ``channel`` names the emulator."""
        return self.channel == "emulated"
