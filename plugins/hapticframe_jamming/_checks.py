"""Checks of the force-rate jamming classifier that ``validate`` runs (import-light)."""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

from hapticframe import Finding, ValidationContext

__all__ = ["check"]

#: What the bundled producers deliver, by type; others (recordings, third-party plugins)
#: are not known before they are built and are not checked.
_CHANNELS: dict[str, frozenset[str]] = {
    "sandbox-force": frozenset({"force_n"}),
    "robotiq-ft300": frozenset({"force_n", "torque_nm"}),
    "force-observer": frozenset({"force_n"}),
    "bno055": frozenset({"acceleration_m_per_s2", "linear_acceleration_m_per_s2",
                         "gravity_m_per_s2", "angular_velocity_rad_per_s", "orientation_wxyz",
                         "calibration"}),
    "biotac": frozenset({"pac", "pdc", "tac", "tdc", "electrodes", "position_m", "contact"}),
    "emd-features": frozenset({"pac_imfs", "pdc_imfs", "electrodes_window"}),
    "sparse-coding": frozenset({"pac_code", "pdc_code", "electrodes_code", "pac_amplitude",
                                "pdc_amplitude", "electrodes_amplitude"}),
}


def check(config: Any, context: ValidationContext) -> Iterator[Finding]:
    """Refuse inputs that are all known not to deliver ``force_channel``."""
    known = {i: _CHANNELS.get(v.type) for i, v in context.inputs.items()}
    if not known or any(channels is None for channels in known.values()):
        return
    if not any(config.force_channel in channels for channels in known.values() if channels):
        described = "; ".join(
            f"{i} ({context.inputs[i].type}) delivers {', '.join(sorted(c or ()))}"
            for i, c in known.items()
        )
        yield Finding(
            f"the classifier reads the force from channel {config.force_channel!r}, which "
            f"none of its inputs delivers ({described}); wire it to a force sensor or set "
            "force_channel",
            field="force_channel",
        )
