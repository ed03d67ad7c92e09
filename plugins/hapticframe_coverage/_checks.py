"""Checks of the coverage planners that ``validate`` runs (import-light: no numpy).

Across components: the step over each robot's control period against the failure zone
ahead of the fingertip (the core checks the steps per line and the step against the
smallest object for every planner), and the search region against the line spacing and the
map-sampling grids.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from typing import Any

from hapticframe import Finding, Kind, Size, ValidationContext

__all__ = ["check"]


def _ceil(value: float) -> float:
    """``math.ceil`` that keeps an infinite count (a spacing of 5e-324 m) infinite."""
    return float(math.ceil(value)) if math.isfinite(value) else value

#: The thesis's 75 x 50 cm search area: the region when neither config, map nor scene gives one.
_DEFAULT_REGION = (0.0, 0.75, 0.0, 0.50)
#: Most map samples the two-phase planner's centroid grid and line scores may take.
_MAX_GRID_POINTS = 10_000_000
_MAX_LINE_POINTS = 1_000_000
#: Depth and rake angle assumed for a robot that does not say (the thesis's 4.4 cm, vertical).
_DEPTH_M = 0.044


def _bounds(region: Any) -> tuple[float, float, float, float]:
    return (region.x_min_m, region.x_max_m, region.y_min_m, region.y_max_m)


def _region(config: Any, context: ValidationContext) -> tuple[float, float, float, float]:
    """The search region as the planner resolves it: its own, its first map's, the scene's."""
    if config.region is not None:
        return _bounds(config.region)
    for view in context.inputs.values():
        region = getattr(view.config, "region", None)
        if view.kind == Kind.MAP and region is not None:
            return _bounds(region)
    if context.scene is not None:
        return _bounds(context.scene.region)
    return _DEFAULT_REGION


def _shear_band_angle_rad(robot: Any, scene: Any) -> float:
    """β: the robot's, else the Arthur angle π/4 − (φ + ψ)/4 of the scene's material."""
    beta = getattr(robot, "shear_band_angle_deg", None)
    if beta is not None:
        return math.radians(beta)
    material = getattr(scene, "material", None)
    phi = getattr(material, "friction_angle_deg", 42.0)
    psi = getattr(material, "dilation_angle_deg", 12.0)
    return math.pi / 4 - math.radians(phi + psi) / 4


def _failure_zone_m(config: Any, robot: Any, scene: Any) -> float:
    """The shortest rupture distance r = d (cot α + cot β) the robot rakes at."""
    depth = config.depth_m if config.depth_m is not None else getattr(robot, "depth_m", None)
    depth = _DEPTH_M if depth is None else depth
    depth = min(depth, getattr(robot, "min_depth_m", depth))
    alpha = math.radians(getattr(robot, "rake_angle_deg", 90.0))
    beta = _shear_band_angle_rad(robot, scene)
    return float(depth * (1.0 / math.tan(alpha) + 1.0 / math.tan(beta)))


def _robots(context: ValidationContext) -> list[tuple[str, Any, float]]:
    """(id, config, control rate) of every robot that declares its control rate."""
    robots = []
    for view in context.components.values():
        rate = getattr(view.config, "control_rate_hz", None)
        if view.kind == Kind.ROBOT and isinstance(rate, (int, float)) and rate > 0:
            robots.append((view.id, view.config, float(rate)))
    return robots


def _speed(config: Any, context: ValidationContext) -> Iterator[Finding]:
    """A step no longer than the failure zone ahead of the fingertip. (That a line ends
    within the step limit and a step cannot jump over an object, the core checks for every
    planner with a speed.)"""
    speed = config.speed_m_per_s
    for robot_id, robot, rate in _robots(context):
        step = speed / rate
        zone = _failure_zone_m(config, robot, context.scene)
        if zone > 0 and step >= zone:
            yield Finding(
                f"{speed:g} m/s with robot {robot_id!r} at {rate:g} Hz moves "
                f"{step * 1e3:.3g} mm per control step, longer than the {zone * 1e3:.3g} mm "
                "failure zone ahead of the fingertip: jamming cannot be seen before the plate "
                "passes it; lower the speed",
                field="speed_m_per_s",
            )


#: Bytes a planner holds per candidate line (offsets, end points, clipping temporaries),
#: per sampled point of a line score (coordinates, line index, map mean and std, score
#: terms) and per approach direction (direction, room, masks, gap scores).
_LINE_BYTES = 96
_POINT_BYTES = 64
_DIRECTION_BYTES = 48


def _lines(width: float, height: float, spacing: float) -> float:
    """Lines of ``spacing`` across the rectangle at the worst angle (its diagonal)."""
    return max(1.0, _ceil(math.hypot(width, height) / spacing - 1e-9))


def _sizes(config: Any, width: float, height: float) -> Iterator[Size]:
    """What the planner's spacings and steps allocate and iterate over, per decision."""
    region = f"the {width:.3g} x {height:.3g} m search region"
    lines = _lines(width, height, config.line_spacing_m)
    yield Size("line_spacing_m", f"{lines:.3g} coverage lines across {region}",
               bytes=_LINE_BYTES * lines, iterations=lines, remedy="increase line_spacing_m")
    phase2 = getattr(config, "phase2_line_spacing_m", None)
    if phase2 is None:
        return
    candidates = _lines(width, height, phase2)
    yield Size("phase2_line_spacing_m",
               f"{candidates:.3g} candidate lines across {region} per phase-2 movement",
               bytes=_LINE_BYTES * candidates, iterations=candidates,
               remedy="increase phase2_line_spacing_m")
    directions = _ceil(360.0 / config.gap_step_deg - 1e-9)
    yield Size("gap_step_deg", f"{directions:.3g} approach directions per phase-2 movement",
               bytes=_DIRECTION_BYTES * directions, iterations=directions,
               remedy="increase gap_step_deg")
    points = candidates * math.hypot(width, height) / config.score_step_m
    yield Size("score_step_m",
               f"{points:.3g} map samples along {candidates:.3g} candidate lines per phase-2 "
               "movement", bytes=_POINT_BYTES * points, iterations=points,
               remedy="increase score_step_m or phase2_line_spacing_m")
    grid = (width / config.grid_spacing_m + 1) * (height / config.grid_spacing_m + 1)
    yield Size("grid_spacing_m", f"{grid:.3g} map samples of the centroid grid over {region}",
               bytes=_POINT_BYTES * grid, iterations=grid, remedy="increase grid_spacing_m")


def check(config: Any, context: ValidationContext) -> Iterator[Finding | Size]:
    """Yield the coverage planner's cross-component findings (see the module docstring)
    and the sizes of its lines, directions and map samples."""
    x0, x1, y0, y1 = _region(config, context)
    width, height = x1 - x0, y1 - y0
    spacing = config.line_spacing_m
    if max(width, height) < spacing:
        yield Finding(
            f"the {width:.3g} x {height:.3g} m search region is smaller than one coverage line "
            f"spacing ({spacing:g} m): lower line_spacing_m or enlarge the region",
            field="line_spacing_m",
        )
    yield from _speed(config, context)
    yield from _sizes(config, width, height)
    map_id = getattr(config, "map_id", None)
    if map_id is not None and map_id not in context.inputs:
        yield Finding(
            f"map_id {map_id!r} is not one of the planner's inputs {list(context.inputs)}",
            field="map_id",
        )
    grid = getattr(config, "grid_spacing_m", None)
    if grid is not None:
        points = (width / grid + 1) * (height / grid + 1)
        if points > _MAX_GRID_POINTS:
            yield Finding(
                f"grid spacing {grid:g} m gives {points:.3g} map samples over the "
                f"{width:.3g} x {height:.3g} m region; the limit is {_MAX_GRID_POINTS:.0e}",
                field="grid_spacing_m",
            )
    step = getattr(config, "score_step_m", None)
    if step is not None and math.hypot(width, height) / step > _MAX_LINE_POINTS:
        yield Finding(
            f"score step {step:g} m gives {math.hypot(width, height) / step:.3g} points per "
            f"candidate line; the limit is {_MAX_LINE_POINTS:.0e}",
            field="score_step_m",
        )
