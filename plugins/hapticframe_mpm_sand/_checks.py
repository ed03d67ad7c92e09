"""The engine's two physical checks (issue 29), for the tests and ``bench physics-checks``.

1. Free drag against depth: the steady drag (mean over the last half of a movement, after
   the start-up) at three or more depths, fitted by ``F = c d**n``; the dissertation's
   account (section 3.2, the Wick–Perumpral failure zone) gives about ``n = 2``.
2. The rise ahead of a buried cylinder: the plate raked at the cylinder's centre line, the
   force against the same movement in free sand; how far ahead of the cylinder's leading
   point the force first stays at least 10 % above free drag, and the ratio at 2 and 1 cm.

Both run the engine (``physics`` extra); :func:`run_physics_checks` is the bench suite.
"""

from __future__ import annotations

import dataclasses
import importlib.util
import json
import math
import os
import time
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np
from numpy.typing import NDArray

from hapticframe import UsageError

from ._engine import EngineSettings, RakeCase, RakeResult, rake
from ._library import fit_power_law
from .build_library import TRAVEL_M, ShapeSpec, object_case, shape_case, smooth

__all__ = ["DragDepthCheck", "HeldOutError", "Reach", "RiseCheck", "drag_depth_check",
           "held_out_error", "library_reach", "onset_distance", "rise_check", "rise_profile",
           "run_physics_checks"]


@dataclasses.dataclass(frozen=True)
class DragDepthCheck:
    depths_m: tuple[float, ...]
    steady_drag_n: tuple[float, ...]
    exponent: float
    coefficient: float
    particles: int
    cpu_s: float


@dataclasses.dataclass(frozen=True)
class RiseCheck:
    depth_m: float
    radius_m: float
    free_drag_n: float
    #: How far ahead of the leading point the (smoothed) force first stays >= 1.1 x free
    #: (up to TOUCH_MARGIN_M before it; 0 when it never does).
    rise_distance_m: float
    ratio_at_2cm: float
    ratio_at_1cm: float
    ratio_at_touch: float
    particles: int
    cpu_s: float


#: The rise is measured up to this distance before the leading point.
TOUCH_MARGIN_M = 0.005


def _rupture_cm(depth_m: float) -> float:
    """The failure-zone model's rupture distance for the examples' sand, in cm."""
    from hapticframe_granular import arthur_angle, rupture_distance

    beta = arthur_angle(math.radians(42.0), math.radians(12.0))
    return 100 * float(rupture_distance(depth_m, math.pi / 2, beta))


def _window(settings: EngineSettings, case: RakeCase) -> int:
    return max(1, round(settings.voxel_size_m / (case.speed_m_per_s * settings.step_s)))


def drag_depth_check(settings: EngineSettings, depths_m: Sequence[float],
                     travel_m: float = TRAVEL_M, seed: int = 0) -> DragDepthCheck:
    """Steady free drag at each depth and the fitted power law."""
    drags, cpu, particles = [], 0.0, 0
    for depth in depths_m:
        run = rake(RakeCase(depth_m=depth, travel_m=travel_m), settings, seed=seed)
        drag = -run.force_n[:, 0]
        drags.append(float(drag[drag.size // 2:].mean()))
        cpu += run.cpu_s
        particles = run.particle_count
    c, n = fit_power_law(np.asarray(depths_m, dtype=np.float64), np.asarray(drags))
    return DragDepthCheck(tuple(float(d) for d in depths_m), tuple(drags), n, c, particles, cpu)


def rise_profile(free: RakeResult, run: RakeResult, case: RakeCase, settings: EngineSettings
                 ) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """The smoothed force ratio of ``run`` (towards the object of ``case``) to ``free``.

    Returns ``(s, ratio, free_drag)`` per step of ``run``: ``s`` the plate front's position
    relative to the object's leading point (m, negative ahead of it), ``ratio`` the force
    along x over the free drag at the same step, both smoothed over one cell of travel, and
    the smoothed free drag (N).
    """
    window = _window(settings, case)
    free_drag = smooth(-free.force_n[:, 0], window)
    ratio = smooth(-run.force_n[:, 0], window) / np.maximum(free_drag, 1e-9)
    s = run.x_m - (case.start_x_m + case.travel_m)
    return s, ratio, free_drag


def onset_distance(s: NDArray[np.float64], ratio: NDArray[np.float64],
                   threshold: float = 1.1, startup_m: float = TRAVEL_M / 2) -> float:
    """How far ahead of the leading point ``ratio`` first stays >= ``threshold`` (m).

    Only after the start-up (``startup_m`` of travel past the first step; the bench: half the
    travel) does the comparison mean anything, and only until TOUCH_MARGIN_M before the
    leading point: at touch the sand squeezes out (no contact in the engine) and the
    smoothing window is cut at the run's end. 0 when it never does; the answer cannot exceed
    ``-(s[0] + startup_m)``, the farthest it looks.
    """
    settled = (s >= s[0] + startup_m) & (s <= -TOUCH_MARGIN_M)
    above = (ratio >= threshold) & settled
    # The first s from which the ratio stays above the threshold to the end.
    below = np.nonzero(~above & settled)[0]
    first = (below[-1] + 1) if below.size else int(np.argmax(settled))
    return float(-s[first]) if first < s.size and settled[first] else 0.0


def rise_check(settings: EngineSettings, depth_m: float = 0.044, radius_m: float = 0.03,
               seed: int = 0) -> RiseCheck:
    """The force ahead of a cylinder on the plate's centre line, against free sand."""
    free = rake(RakeCase(depth_m=depth_m, travel_m=TRAVEL_M), settings, seed=seed)
    case = object_case(depth_m, radius_m, 0.0)
    run = rake(case, settings, seed=seed)
    s, ratio, free_drag = rise_profile(free, run, case, settings)
    return RiseCheck(
        depth_m=depth_m, radius_m=radius_m,
        free_drag_n=float(free_drag[free_drag.size // 2:].mean()),
        rise_distance_m=onset_distance(s, ratio),
        ratio_at_2cm=float(np.interp(-0.02, s, ratio)),
        ratio_at_1cm=float(np.interp(-0.01, s, ratio)),
        ratio_at_touch=float(ratio[-1]),
        particles=run.particle_count, cpu_s=free.cpu_s + run.cpu_s,
    )


def run_physics_checks(options: Any) -> dict[str, Any]:
    """``hapticframe bench physics-checks``: both checks at the bench resolution (5 mm cells;
    ``--quick``: 7.5 mm), written to ``physics-checks.json`` and ``physics-checks.md``."""
    echo: Callable[[str], None] = getattr(options, "echo", print)
    if importlib.util.find_spec("newton") is None:  # checked before any work, not mid-run
        raise UsageError("bench physics-checks runs the engine itself: pip install "
                         "'hapticframe[physics]' (NVIDIA Newton on Warp, about 480 MB)")
    voxel = 0.0075 if options.quick else 0.005
    settings = EngineSettings(voxel_size_m=voxel)
    depths = (0.02, 0.03, 0.044)
    load = os.getloadavg()[0]
    start = time.perf_counter()
    echo(f"free drag at depths {', '.join(f'{d * 100:g}' for d in depths)} cm, "
         f"{voxel * 1000:g} mm cells")
    drag = drag_depth_check(settings, depths, seed=options.seed)
    echo(f"  exponent {drag.exponent:.2f}")
    echo("rise ahead of a 3 cm cylinder at 4.4 cm depth")
    rise = rise_check(settings, seed=options.seed)
    echo(f"  +10 % from {rise.rise_distance_m * 100:.1f} cm, x{rise.ratio_at_1cm:.2f} at 1 cm")
    result: dict[str, Any] = {
        "voxel_size_m": voxel, "step_s": settings.step_s,
        "particles_per_cell": settings.particles_per_cell,
        "drag_depth": dataclasses.asdict(drag), "rise": dataclasses.asdict(rise),
        "wall_s": time.perf_counter() - start, "load_average_1min": load,
    }
    out = options.out_dir
    out.mkdir(parents=True, exist_ok=True)
    (out / "physics-checks.json").write_text(json.dumps(result, indent=2) + "\n")
    rows = [
        "| check | engine | dissertation (section 3.2) |",
        "|---|---|---|",
        f"| free drag exponent n in F = c d^n ({len(depths)} depths) | {drag.exponent:.2f} "
        "| about 2 |",
        f"| steady free drag at 2 / 3 / 4.4 cm (2 cm plate) | "
        f"{' / '.join(f'{f:.2f}' for f in drag.steady_drag_n)} N | about 15 N at 4.4 cm "
        "(Figure 3.6, its own plate and sand) |",
        f"| force >= 1.1 x free, from ahead of a 3 cm cylinder | "
        f"{rise.rise_distance_m * 100:.1f} cm | the failure zone's rupture distance, "
        f"{_rupture_cm(rise.depth_m):.1f} cm (φ 42°, ψ 12°, vertical plate) |",
        f"| force / free drag at 2 cm, 1 cm, touch | {rise.ratio_at_2cm:.2f}, "
        f"{rise.ratio_at_1cm:.2f}, {rise.ratio_at_touch:.2f} | a surge (jamming) |",
    ]
    (out / "physics-checks.md").write_text(
        f"# Physical checks of the engine (NVIDIA Newton, implicit MPM)\n\n"
        f"{voxel * 1000:g} mm cells, {settings.particles_per_cell:g} particles per cell, "
        f"{settings.step_s * 1000:g} ms steps, {drag.particles} particles; load average "
        f"{load:.1f} on {os.cpu_count()} CPUs.\n\n" + "\n".join(rows) + "\n")
    return {"drag_exponent": drag.exponent, "rise_distance_m": rise.rise_distance_m,
            "ratio_at_1cm": rise.ratio_at_1cm}


@dataclasses.dataclass(frozen=True)
class HeldOutError:
    """The library against a direct engine run at one configuration not on its grid."""

    depth_m: float
    #: A cylinder's radius; 0 for a shape table's object (``shape``, ``yaw_deg``).
    radius_m: float
    offset_u: float
    voxel_size_m: float
    #: RMS of (library − direct) force along x over the last 4 cm before the leading point,
    #: relative to the direct run's steady free drag.
    rms_relative: float
    #: The same for the ratio to free drag (the shape of the rise, the level removed).
    ratio_rms: float
    direct_ratio_at_1cm: float
    library_ratio_at_1cm: float
    cpu_s: float
    shape: int = -1
    yaw_deg: float = 0.0


def held_out_error(library: Any, settings: EngineSettings, depth_m: float, radius_m: float,
                   offset_u: float, seed: int = 1, shape: ShapeSpec | None = None,
                   shape_index: int = -1, yaw_deg: float = 0.0) -> HeldOutError:
    """Compare ``library`` with direct runs (free and towards the object) at ``settings``.

    The object is a cylinder of ``radius_m`` at offset ``offset_u`` (>= 0), or, with
    ``shape``, that shape at ``yaw_deg`` and signed ``offset_u``, compared with the
    library's table ``shape_index`` (a run with the object on the right is made as its
    mirror image, whose y force does not enter the comparison).
    """
    # The library's own approach: its s grid starts one spacing after the run's start.
    travel = float(library.s_m[1] - 2 * library.s_m[0])
    free = rake(RakeCase(depth_m=depth_m, travel_m=travel), settings, seed=seed)
    if shape is None:
        case = object_case(depth_m, radius_m, offset_u, travel)
    elif offset_u >= 0:
        case = shape_case(depth_m, shape, yaw_deg, offset_u, travel)
    else:
        case = shape_case(depth_m, shape, -yaw_deg, -offset_u, travel)
    run = rake(case, settings, seed=seed)
    window = _window(settings, case)
    free_drag = smooth(-free.force_n[:, 0], window)
    direct = smooth(-run.force_n[:, 0], window)
    s = run.x_m - (case.start_x_m + travel)
    travelled = run.x_m - case.start_x_m
    if shape is None:
        predicted_ratio = np.array([library.ratio(depth_m, radius_m, offset_u, v)[0] for v in s])
    else:
        predicted_ratio = np.array([library.shape_ratio(depth_m, shape_index, yaw_deg,
                                                        offset_u, v)[0] for v in s])
    predicted = predicted_ratio * np.array([library.free_drag(depth_m, t) for t in travelled])
    steady = float(free_drag[free_drag.size // 2:].mean())
    near = s >= -0.04
    direct_ratio = direct / np.maximum(free_drag, 1e-9)
    return HeldOutError(
        depth_m=depth_m, radius_m=radius_m if shape is None else 0.0, offset_u=offset_u,
        voxel_size_m=settings.voxel_size_m,
        rms_relative=float(np.sqrt(np.mean((predicted[near] - direct[near]) ** 2)) / steady),
        ratio_rms=float(np.sqrt(np.mean((predicted_ratio[near] - direct_ratio[near]) ** 2))),
        direct_ratio_at_1cm=float(np.interp(-0.01, s, direct_ratio)),
        library_ratio_at_1cm=float(np.interp(-0.01, s, predicted_ratio)),
        cpu_s=free.cpu_s + run.cpu_s, shape=shape_index if shape is not None else -1,
        yaw_deg=yaw_deg,
    )


@dataclasses.dataclass(frozen=True)
class Reach:
    """How far a library's objects act on the plate: for one table row (a cylinder's
    radius, or a shape at a yaw) at one depth."""

    depth_m: float
    #: "cylinder r=…" or "shape N yaw …".
    label: str
    #: How far ahead of the leading point the x ratio first stays >= the threshold, dead
    #: ahead (offset 0); the library's whole approach when it already is at its start.
    ahead_m: float
    #: True when the ratio is at or above the threshold at the library's farthest point
    #: (the reach is at least its approach; longer runs would tell more).
    ahead_at_edge: bool
    #: The largest offset u (either side) at which the x ratio reaches the threshold
    #: anywhere on the approach; the library's widest when it does there.
    lateral_u: float
    lateral_at_edge: bool


def library_reach(library: Any, threshold: float = 1.1) -> list[Reach]:
    """Measured reach of every table of ``library`` (cylinders and shapes), per depth."""
    # As the onset check: up to TOUCH_MARGIN_M before the leading point (where the engine's
    # squeezed sand, not jamming, sets the force).
    keep = np.asarray(library.s_m) <= -TOUCH_MARGIN_M
    s = np.asarray(library.s_m)[keep]
    rows: list[Reach] = []

    def one(depth: float, label: str, offsets: NDArray[np.float64],
            ratio: NDArray[np.float64]) -> Reach:
        # ratio: (offset, s); the dead-ahead row is the offset nearest 0.
        ratio = ratio[:, keep]
        centre = int(np.argmin(np.abs(offsets)))
        above = ratio[centre] >= threshold
        below = np.nonzero(~above)[0]
        first = below[-1] + 1 if below.size else 0
        ahead = float(-s[first]) if first < s.size else 0.0
        reaching = np.nonzero((ratio >= threshold).any(axis=1))[0]
        lateral = float(np.abs(offsets[reaching]).max()) if reaching.size else 0.0
        widest = float(np.abs(offsets).max())
        return Reach(depth, label, ahead, bool(above[0]), lateral,
                     bool(reaching.size and lateral >= widest))

    for i, depth in enumerate(library.depths_m):
        for j, radius in enumerate(library.radii_m):
            rows.append(one(float(depth), f"cylinder r={radius * 100:g} cm",
                            np.asarray(library.offsets_u), library.ratio_x[i, j]))
        for n in range(library.shape_count):
            for m, yaw in enumerate(library.shape_yaws_deg):
                rows.append(one(float(depth), f"shape {n} yaw {yaw:g} deg",
                                np.asarray(library.shape_offsets_u),
                                library.shape_ratio_x[i, n, m]))
    return rows
