"""Checks of the force observer that ``validate`` runs (import-light)."""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

from hapticframe import Finding, ValidationContext

__all__ = ["check"]

#: What the bundled sensors deliver, by type; others (recordings, third-party plugins) are
#: not known before they are built and are not checked.
_CHANNELS: dict[str, frozenset[str]] = {
    "sandbox-force": frozenset({"force_n"}),
    "robotiq-ft300": frozenset({"force_n", "torque_nm"}),
    "bno055": frozenset({"acceleration_m_per_s2", "linear_acceleration_m_per_s2",
                         "gravity_m_per_s2", "angular_velocity_rad_per_s", "orientation_wxyz",
                         "calibration"}),
    "biotac": frozenset({"pac", "pdc", "tac", "tdc", "electrodes", "position_m", "contact"}),
}


def check(config: Any, context: ValidationContext) -> Iterator[Finding]:
    """Refuse inputs that are all known not to deliver the force or the IMU channel."""
    known = {i: _CHANNELS.get(v.type) for i, v in context.inputs.items()}
    if not known or any(channels is None for channels in known.values()):
        return
    fields = ["force_channel"]
    if config.model_dir is not None or config.mass_kg:
        fields.append("acceleration_channel")  # zero mass passes the force through
    for field in fields:
        channel = getattr(config, field)
        if not any(channel in (channels or ()) for channels in known.values()):
            yield Finding(
                f"channel {channel!r} is delivered by none of the observer's inputs "
                f"({', '.join(f'{i} ({context.inputs[i].type})' for i in known)}); wire a "
                f"sensor that delivers it or set {field}",
                field=field,
            )
