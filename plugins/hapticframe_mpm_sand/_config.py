"""Config model of the ``mpm-sand`` world (import-light: neither engine nor library loads)."""

from __future__ import annotations

from pydantic import Field

from hapticframe_sandbox import SandboxRobotConfig

__all__ = ["BUNDLED_LIBRARIES", "MpmSandRobotConfig"]

#: The libraries shipped in ``data/``, by the engine's voxel size (m) they were built at:
#: 7.5 mm cells at 7.5 ms steps with shape tables (issue 32), and the first library's
#: 10 mm companion (30 ms steps, cylinders only). The first 7.5 mm library (30 ms steps)
#: is shipped as ``response-library-7.5mm-30ms.npz`` for ``library_path``.
BUNDLED_LIBRARIES = {0.0075: "response-library.npz", 0.01: "response-library-10mm.npz"}


class MpmSandRobotConfig(SandboxRobotConfig):
    """A plate raked through sand whose forces come from NVIDIA Newton's material-point solver.

    Every field of the ``sandbox`` robot applies (depth schedule, control rate, plate width,
    contact stiffness, force limit, workspace, ``follows``); its analytic drag, shear-band
    and jamming fields are not used. The forces come from a response library built by the
    engine (``python -m hapticframe_mpm_sand.build_library``); see docs/physics-world.md.
    """

    voxel_size_m: float = Field(
        0.0075, gt=0, le=0.1,
        description="The engine's grid cell of the bundled library to use: 0.0075 (7.5 ms "
        "steps, ellipse and box tables) or 0.01 m (30 ms steps, cylinders only); ignored when "
        "library_path is set.",
    )
    library_path: str | None = Field(
        None, max_length=4096,
        description="A response library file (.npz) built by the build command; None: the "
        "bundled one at voxel_size_m.",
    )
    jamming_label_ratio: float = Field(
        1.1, gt=1, le=100,
        description="Ground truth: a step is labelled jamming when the library's force is at "
        "least this multiple of the free drag (the engine's own account of jamming).",
    )
    offset_taper_u: float = Field(
        0.5, gt=0, le=10,
        description="Beyond the library's widest offset u_max the object's effect tapers "
        "linearly to none at u_max + this (an assumption, not an engine run).",
    )
    drag_fluctuation_fraction: float = Field(
        0.03, ge=0, le=1,
        description="Std of a slow random drag fluctuation added to the library's smoothed "
        "drag, relative to the drag.",
    )
