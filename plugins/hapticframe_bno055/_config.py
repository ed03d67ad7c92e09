"""Config model of the BNO055 IMU sensor (import-light: pydantic and hapticframe only)."""

from __future__ import annotations

from typing import Annotated, Literal

from pydantic import Field, model_validator

from hapticframe import PluginConfig
from hapticframe.devices import FaultKind, FaultKinds, FaultParam, FaultValue

__all__ = ["FAULT_KINDS", "EMULATED_PORT", "Bno055SensorConfig"]

#: The emulator's own fault kinds (hapticframe_bno055._emulator.MODEL_FAULT_KINDS); the
#: harness adds the byte-level ones. ``validate`` refuses any other kind and parameter.
_TIMES = {"count": FaultParam(1, 10**9, integer=True)}  # a counter: 1e9 = never answers
FAULT_KINDS: dict[str, FaultKind] = {
    "bus_overrun": FaultKind("params.count requests answered BUS_OVER_RUN_ERROR", _TIMES),
    "status": FaultKind("params.count requests answered with status params.code",
                        {**_TIMES, "code": FaultParam(0, 255, integer=True)}),
    "no_reply": FaultKind("params.count requests left unanswered", _TIMES),
    "rx_stall": FaultKind("params.count requests dropped by the character timeout", _TIMES),
    "partial_reply": FaultKind("params.count replies cut to params.keep data bytes",
                               {**_TIMES, "keep": FaultParam(0, 255, integer=True)}),
    "wrong_length": FaultKind("params.count replies whose length byte is off by params.delta",
                              {**_TIMES, "delta": FaultParam(-255, 255, integer=True)}),
    "stale_bytes": FaultKind("params.count bytes of the previous reply before one reply",
                             {"count": FaultParam(1, 255, integer=True)}),
    "reset": FaultKind("the chip resets (silent for its boot time)"),
    "calib_drop": FaultKind("the calibration status reads params.stat for duration_s",
                            {"stat": FaultParam(0, 255, integer=True)}),
    "bad_quaternion": FaultKind("the quaternion scaled by params.scale for duration_s",
                                {"scale": FaultParam(-10.0, 10.0)}),
    "bad_gravity": FaultKind("the gravity vector scaled by params.scale for duration_s",
                             {"scale": FaultParam(-10.0, 10.0)}),
}
#: The ``port`` value that runs the built-in emulator behind a pseudo-terminal.
EMULATED_PORT = "emulated"


class Bno055SensorConfig(PluginConfig):
    """A Bosch BNO055 IMU on a UART (115200 8N1), polled by burst reads of its data registers.

    ``port: emulated`` runs the emulator behind a real pseudo-terminal, driven by the
    physical truth of the robot input (at rest and level without one); any other value is a
    device path or a pyserial URL.
    """

    port: str = Field(
        EMULATED_PORT, min_length=1,
        description="Device path (/dev/ttyUSB0), pyserial URL, or 'emulated'.",
    )
    mode: Literal["ndof", "accgyro"] = Field(
        "ndof",
        description="Output mode: 'ndof' (9-axis fusion: orientation, gravity, linear "
        "acceleration) or 'accgyro' (raw accelerometer and gyroscope only; the fused "
        "channels are then invalid).",
    )
    rate_hz: float = Field(
        100.0, gt=0, le=100, description="Polls per second (the fusion runs at 100 Hz)."
    )
    reply_timeout_s: float = Field(
        0.05, gt=0, le=1,
        description="How long one request waits for its reply (above the chip's 30 ms "
        "character timeout, so that an EE 0A is seen).",
    )
    poll_step_s: float = Field(
        0.001, gt=0, le=0.01, description="Sleep between checks for reply bytes."
    )
    max_retries: int = Field(
        3, ge=0, le=20,
        description="Resends of one request after a bus overrun (EE 07), a character "
        "timeout (EE 0A), a timeout or a malformed reply.",
    )
    watchdog_s: float = Field(
        0.25, gt=0, le=60.0,
        description="No valid reply for this long → recover (reconnect, reconfigure)."
    )
    max_recoveries: int = Field(
        3, ge=0, le=20, description="Recoveries in a row before the device gives up (DeviceError)."
    )
    reconnect_attempts: int = Field(
        5, ge=1, le=50, description="Reopen attempts (with backoff) within one recovery."
    )
    chip_id_attempts: int = Field(
        3, ge=1, le=20, description="CHIP_ID reads before configure gives up."
    )
    reset_on_configure: bool = Field(
        False, description="Reset the chip (SYS_TRIGGER, 650 ms) before configuring it."
    )
    quaternion_norm_tolerance: float = Field(
        0.01, gt=0, lt=1, description="A quaternion whose |norm − 1| exceeds this is invalid."
    )
    gravity_tolerance_m_per_s2: float = Field(
        0.5, gt=0,
        le=9.8, description="Fused samples are invalid when |gravity| differs from 9.80665 m/s² by "
        "more than this, or the gravity vector disagrees with the quaternion by more.",
    )
    check_gravity_against_quaternion: bool = Field(
        True,
        description="Also require the gravity vector to match the quaternion "
        "(gravity = Rᵀ (0, 0, g) with R = world ← IMU).",
    )
    min_system_calibration: int = Field(
        0, ge=0, le=3,
        description="Fused channels are invalid while the system calibration level is below this.",
    )
    mount_rpy_deg: tuple[float, float, float] = Field(
        (0.0, 0.0, 0.0),
        description="Emulated only: the IMU's misalignment R_ti on the tool (roll, pitch, yaw).",
    )
    accel_noise_std_m_per_s2: float = Field(
        0.015, ge=0, le=10.0, description="Emulated only: accelerometer noise per axis."
    )
    faults: Annotated[FaultValue, FaultKinds(FAULT_KINDS)] = Field(
        "none",
        description="Emulated only: no faults, the 'standard' schedule, or a list of "
        "FaultEvent entries ({kind, at_s | rate_hz, duration_s, params}).",
    )

    @model_validator(mode="after")
    def _emulator_options_need_emulation(self) -> Bno055SensorConfig:
        if self.port != EMULATED_PORT and self.faults != "none":
            raise ValueError("faults apply to port: emulated only")
        return self

    @property
    def emulated(self) -> bool:
        """True when ``port`` is ``"emulated"``."""
        return self.port == EMULATED_PORT
