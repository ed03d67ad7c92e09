"""Checks for the spatial kinds: sensor models, maps, planners and robots; and determinism."""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from hapticframe._kind import Kind
from hapticframe._registry import Registry
from hapticframe._scene import RegionConfig, Scene
from hapticframe._specs import PluginSpec
from hapticframe.kinds import (
    Classifier,
    ExploratoryMovement,
    FeatureExtractor,
    LocatedMeasurement,
    Map,
    MapEstimate,
    MovementResult,
    Observations,
    Planner,
    Region,
    Robot,
    RobotState,
    Sensor,
    SensorModel,
)
from hapticframe.run._components import INTERFACES
from hapticframe.testing._common import check, outputs_equal
from hapticframe.testing._harness import (
    DEFAULT_SCENE,
    CheckFailure,
    KitMap,
    crossing_movement,
    make_component,
    raised_by_record_validation,
    release_component,
)
from hapticframe.testing._streams import exercise_stream, sensor_outputs

__all__ = [
    "TINY_SCENE",
    "FixedMap",
    "KitMap",
    "check_planner_extremes",
    "check_robot_extremes",
    "check_robot_refuses_bad_depth",
    "check_robot_refuses_outside_workspace",
    "check_robot_stops_at_once",
    "located_measurement",
    "map_observations",
    "planner_episode",
]

CLASSES = ("free", "jamming", "contact")


def located_measurement(
    n: int = 60, *, y: float = 0.25, depth: float = 0.044
) -> LocatedMeasurement:
    """A fingertip moving along +x: free movement, then jamming, then contact."""
    t = np.asarray(0.01 * (1 + np.arange(n)), dtype=np.float64)
    x = 0.10 + 0.0005 * np.arange(n)
    labels = np.zeros(n, dtype=int)
    labels[int(0.7 * n):] = 1
    labels[int(0.9 * n):] = 2
    return LocatedMeasurement(
        t, np.column_stack([x, np.full(n, y)]), np.zeros(n), np.eye(3)[labels], CLASSES,
        np.full(n, depth),
    )


def map_observations(seed: int, n: int = 400, scene: Scene = DEFAULT_SCENE) -> Observations:
    """Random points of the scene's region labelled by the scene (with 3 % label noise)."""
    rng = np.random.default_rng(seed)
    region = scene.region.to_region()
    pts = np.column_stack([
        rng.uniform(region.x_min_m, region.x_max_m, n),
        rng.uniform(region.y_min_m, region.y_max_m, n),
    ])
    labels = scene.occupied(pts).astype(float)
    flip = rng.random(n) < 0.03
    labels[flip] = 1 - labels[flip]
    return Observations(pts, labels)


def _query_grid(the_map: Map) -> np.ndarray:
    r = the_map.region
    gx, gy = np.meshgrid(
        np.linspace(r.x_min_m, r.x_max_m, 31), np.linspace(r.y_min_m, r.y_max_m, 21)
    )
    return np.column_stack([gx.ravel(), gy.ravel()])


def _invalid(spec: PluginSpec, what: str, exc: Exception) -> CheckFailure:
    origin = (
        "produced invalid output" if raised_by_record_validation(exc)
        else f"raised {type(exc).__name__}"
    )
    return CheckFailure(f"{spec.kind} {spec.name!r} {origin} on {what}: {exc}")


# --- sensor models ---------------------------------------------------------------------------


@check(Kind.SENSOR_MODEL)
def check_sensor_model_contract(spec: PluginSpec, *, registry: Registry | None = None) -> None:
    """Observations are finite points with targets in [0, 1]; empty input gives none."""
    model = make_component(spec, registry=registry, interface=SensorModel)
    try:
        obs = model.observe(located_measurement())
        if not isinstance(obs, Observations):
            raise CheckFailure(f"observe() returned {type(obs).__name__}, not Observations")
        if not len(obs):
            raise CheckFailure("observe() returned no observations for 60 located samples")
        empty = model.observe(located_measurement().select(slice(0, 0)))
        if len(empty):
            raise CheckFailure("observe() of an empty measurement returned observations")
    except CheckFailure:
        raise
    except Exception as exc:
        raise _invalid(spec, "a free → jamming → contact approach", exc) from exc
    finally:
        release_component(model)


@check(Kind.SENSOR_MODEL)
def check_sensor_model_streaming(spec: PluginSpec, *, registry: Registry | None = None) -> None:
    """Observing rows one at a time equals observing them all at once."""
    measurement = located_measurement()
    batch_model = make_component(spec, registry=registry, interface=SensorModel)
    stream_model = make_component(spec, registry=registry, interface=SensorModel)
    try:
        whole = batch_model.observe(measurement)
        parts = [
            stream_model.observe(measurement.select(slice(i, i + 1)))
            for i in range(len(measurement))
        ]
    finally:
        release_component(batch_model)
        release_component(stream_model)
    streamed = Observations.concatenate(parts)
    if streamed.points_m.shape != whole.points_m.shape or not (
        np.allclose(streamed.points_m, whole.points_m, atol=1e-9)
        and np.allclose(streamed.targets, whole.targets, atol=1e-9)
    ):
        raise CheckFailure(
            f"row-by-row observe() gave {len(streamed)} observations, all-at-once {len(whole)} "
            "(or different values)"
        )


@check(Kind.SENSOR_MODEL)
def check_sensor_model_extremes(spec: PluginSpec, *, registry: Registry | None = None) -> None:
    """Single samples, far-away and stationary fingertips, unknown depth: finite or ValueError."""
    base = located_measurement()
    cases = {
        "a single sample": base.select(slice(0, 1)),
        "positions 1e6 m away": LocatedMeasurement(
            base.timestamps_s, base.positions_m + 1e6, base.headings_rad, base.probabilities,
            base.classes, base.depth_m),
        "a stationary fingertip": LocatedMeasurement(
            base.timestamps_s, np.repeat(base.positions_m[:1], len(base), axis=0),
            base.headings_rad, base.probabilities, base.classes, base.depth_m),
        "unknown (NaN) depth": LocatedMeasurement(
            base.timestamps_s, base.positions_m, base.headings_rad, base.probabilities,
            base.classes, np.full(len(base), np.nan)),
        "a tiny depth (1e-9 m)": LocatedMeasurement(
            base.timestamps_s, base.positions_m, base.headings_rad, base.probabilities,
            base.classes, np.full(len(base), 1e-9)),
    }
    for what, measurement in cases.items():
        model = make_component(spec, registry=registry, interface=SensorModel)
        try:
            model.observe(measurement)  # Observations validates finiteness and ranges
        except ValueError as exc:
            if raised_by_record_validation(exc):
                raise _invalid(spec, what, exc) from exc
        except Exception as exc:
            raise _invalid(spec, what, exc) from exc
        finally:
            release_component(model)


# --- maps ------------------------------------------------------------------------------------


@check(Kind.MAP)
def check_map_contract(spec: PluginSpec, *, registry: Registry | None = None) -> None:
    """Queries anywhere (empty, float32, far outside) return means in [0, 1] and finite std."""
    the_map = make_component(spec, registry=registry, interface=Map)
    try:
        grid = _query_grid(the_map)
        for stage in ("before any update", "after an update"):
            if stage == "after an update":
                the_map.update(map_observations(5))
            estimate = the_map.query(grid)
            if estimate.mean.shape != (len(grid),):
                raise CheckFailure(
                    f"query of {len(grid)} points returned shape {estimate.mean.shape} {stage}"
                )
            if the_map.query(np.empty((0, 2))).mean.shape != (0,):
                raise CheckFailure(f"an empty query did not return an empty estimate {stage}")
            the_map.query(grid.astype(np.float32))
            the_map.query(np.array([[1e3, -1e3], [-50.0, 50.0]]))
    except CheckFailure:
        raise
    except Exception as exc:
        raise _invalid(spec, "queries", exc) from exc
    finally:
        release_component(the_map)


@check(Kind.MAP)
def check_map_streaming_matches_batch(
    spec: PluginSpec, *, registry: Registry | None = None
) -> None:
    """Two updates give (close to) the map fitted on both batches at once."""
    first, second = map_observations(6), map_observations(7)
    streamed = make_component(spec, registry=registry, interface=Map)
    batch = make_component(spec, registry=registry, interface=Map)
    try:
        streamed.update(first)
        streamed.update(second)
        batch.fit(Observations.concatenate([first, second]))
        grid = _query_grid(batch)
        diff = float(np.max(np.abs(streamed.query(grid).mean - batch.query(grid).mean)))
    finally:
        release_component(streamed)
        release_component(batch)
    tolerance = 1e-9 if "exact-update" in spec.capabilities else 0.1
    if diff > tolerance:
        raise CheckFailure(
            f"sequential updates and one fit differ by {diff:.3g} in mean occupancy "
            f"(allowed {tolerance:g})"
        )


@check(Kind.MAP)
def check_map_extremes(spec: PluginSpec, *, registry: Registry | None = None) -> None:
    """Empty, one-sided, single-point and far-away observations keep the map finite."""
    obs = map_observations(8, n=50)
    cases = {
        "no observations": Observations.empty(),
        "only free space (all targets 0)": Observations(obs.points_m, np.zeros(len(obs))),
        "only occupied space (all targets 1)": Observations(obs.points_m, np.ones(len(obs))),
        "a single observation": Observations(obs.points_m[:1], obs.targets[:1]),
        "observations 1e6 m outside the region": Observations(obs.points_m + 1e6, obs.targets),
        "repeated identical observations": Observations(
            np.repeat(obs.points_m[:1], 200, axis=0), np.ones(200)),
    }
    for what, observations in cases.items():
        the_map = make_component(spec, registry=registry, interface=Map)
        try:
            the_map.update(observations)
            the_map.query(_query_grid(the_map))
            try:
                the_map.query(np.array([[np.nan, 0.1]]))
            except ValueError as exc:
                if raised_by_record_validation(exc):
                    raise _invalid(spec, "a NaN query point", exc) from exc
        except CheckFailure:
            raise
        except Exception as exc:
            raise _invalid(spec, what, exc) from exc
        finally:
            release_component(the_map)


@check(Kind.MAP)
def check_map_refuses_bad_query_points(
    spec: PluginSpec, *, registry: Registry | None = None
) -> None:
    """``query()`` refuses NaN or infinite points and arrays that are not ``(q, 2)`` with a
    ``ValueError``, and answers one ``(2,)`` point with one estimate. ``Map.query`` does this
    before it calls the plugin's ``_query``: a map that overrides ``query`` itself must too."""
    the_map = make_component(spec, registry=registry, interface=Map)
    cases: dict[str, ArrayLike] = {
        "a NaN query point": [[np.nan, 0.1]],
        "an infinite query point": [[0.1, np.inf]],
        "query points of shape (2, 3)": np.full((2, 3), 0.1),
    }
    try:
        for what, points in cases.items():
            try:
                estimate = the_map.query(np.asarray(points, dtype=np.float64))
            except ValueError as exc:
                if not str(exc) or raised_by_record_validation(exc):
                    raise _invalid(spec, what, exc) from exc
                continue
            raise CheckFailure(
                f"query() accepted {what} (mean {np.asarray(estimate.mean).tolist()}): it must "
                "raise ValueError; implement Map._query and leave the checks to Map.query"
            )
        one = the_map.query(np.array([0.1, 0.1]))
        if np.shape(one.mean) != (1,):
            raise CheckFailure(
                f"query() of one (2,) point returned mean of shape {np.shape(one.mean)}, not (1,)"
            )
    finally:
        release_component(the_map)


def _auc(score: np.ndarray, truth: np.ndarray) -> float:
    """Area under the ROC curve: the chance a true point outranks a free one (ties half)."""
    pos, neg = score[truth], score[~truth]
    greater = np.count_nonzero(pos[:, None] > neg[None, :])
    ties = np.count_nonzero(pos[:, None] == neg[None, :])
    return float((greater + 0.5 * ties) / (pos.size * neg.size))


def _scattered_probe(seed: int, scene: Scene = DEFAULT_SCENE) -> tuple[np.ndarray, np.ndarray]:
    """Held-out points: 400 uniform in the region and 100 inside the first object."""
    rng = np.random.default_rng(seed)
    region = scene.region.to_region()
    uniform = np.column_stack([
        rng.uniform(region.x_min_m, region.x_max_m, 400),
        rng.uniform(region.y_min_m, region.y_max_m, 400),
    ])
    # Rejection sampling around the object's centroid (the kit's object is an 8 cm disc).
    near = np.asarray(scene.objects[0].centroid_m) + rng.uniform(-0.05, 0.05, (2000, 2))
    inside = near[scene.occupied(near)][:100]
    points = np.vstack([uniform, inside])
    return points, scene.occupied(points)


#: Training set sizes of the scattered-points check: 3,000 is where a binned map's cells
#: grow coarse enough to hold free and contact observations side by side (issue 16); with
#: fewer, a grid leaves most held-out points in cells never observed.
_SCATTERED_SIZES = (3000,)
_MIN_AUC = 0.8


@check(Kind.MAP)
def check_map_ranks_scattered_points(
    spec: PluginSpec, *, registry: Registry | None = None
) -> None:
    """3,000 uniformly scattered observations around the kit's disc (3 % of labels flipped):
    the mean at held-out points ranks the disc above free ground (AUC of at least 0.8; 0.5
    is chance, below it the map is inverted)."""
    points, truth = _scattered_probe(31)
    for n in _SCATTERED_SIZES:
        the_map = make_component(spec, registry=registry, interface=Map)
        try:
            the_map.update(map_observations(30, n=n))
            mean = np.asarray(the_map.query(points).mean, dtype=np.float64)
        except Exception as exc:
            raise _invalid(spec, f"{n} scattered observations", exc) from exc
        finally:
            release_component(the_map)
        if not np.all(np.isfinite(mean)):
            raise CheckFailure(f"after {n} scattered observations the map's mean has NaN")
        auc = _auc(mean, truth)
        if not auc >= _MIN_AUC:
            inverted = " (below 0.5: the map is inverted)" if auc < 0.5 else ""
            raise CheckFailure(
                f"after {n} uniformly scattered observations around an 8 cm disc, the mean "
                f"occupancy ranks held-out points inside the disc above free ground with AUC "
                f"{auc:.3f}{inverted}; at least {_MIN_AUC} is required: higher evidence of an "
                "object must never lower the mean"
            )


# --- planners --------------------------------------------------------------------------------


def _segment_distance(point: np.ndarray, a: np.ndarray, b: np.ndarray) -> tuple[float, np.ndarray]:
    d = b - a
    length2 = float(d @ d)
    s = 0.0 if length2 == 0 else float(np.clip((point - a) @ d / length2, 0, 1))
    nearest = a + s * d
    return float(np.linalg.norm(point - nearest)), nearest


def planner_episode(planner: Planner, scene: Scene = DEFAULT_SCENE) -> list[ExploratoryMovement]:
    """Feed a planner results as if its movements met the scene's first object."""
    center = scene.objects[0].centroid_m
    maps = [m for m in planner.context.inputs.values() if isinstance(m, Map)]
    movements: list[ExploratoryMovement] = []
    t = 0.0
    for index in range(planner.max_movements + 1):
        movement = planner.propose()
        if movement is None:
            return movements
        if not isinstance(movement, ExploratoryMovement):
            raise CheckFailure(
                f"propose() returned {type(movement).__name__}, not ExploratoryMovement"
            )
        movements.append(movement)
        distance, nearest = _segment_distance(center, movement.start_m, movement.end_m)
        hit = distance < 0.06
        t += movement.length_m / movement.speed_m_per_s
        state = RobotState(t, nearest if hit else movement.end_m, movement.heading_rad)
        if hit:
            for the_map in maps:
                the_map.update(Observations(nearest[None, :], np.ones(1)))
        planner.on_movement_end(MovementResult(
            index, movement, hit, "interaction" if hit else "", state,
            "jamming" if hit else "free",
        ))
    raise CheckFailure(
        f"the planner proposed more than max_movements={planner.max_movements} movements"
    )


def _outside(movements: list[ExploratoryMovement], region: Region, tolerance: float) -> str:
    """The first movement end outside ``region`` (widened by ``tolerance``), described."""
    for number, m in enumerate(movements, start=1):
        for end in (m.start_m, m.end_m):
            inside = (region.x_min_m - tolerance <= end[0] <= region.x_max_m + tolerance
                      and region.y_min_m - tolerance <= end[1] <= region.y_max_m + tolerance)
            if not inside:
                name = f"{m.label!r}" if m.label else f"{number}"
                return (
                    f"movement {name} leaves the search region x {region.x_min_m:g}..."
                    f"{region.x_max_m:g} m, y {region.y_min_m:g}...{region.y_max_m:g} m at "
                    f"({end[0]:.4g}, {end[1]:.4g}) m"
                )
    return ""


@check(Kind.PLANNER)
def check_planner_contract(spec: PluginSpec, *, registry: Registry | None = None) -> None:
    """Movements lie in the search region and the search ends within ``max_movements``."""
    planner = make_component(spec, registry=registry, interface=Planner)
    try:
        movements = planner_episode(planner)
    finally:
        release_component(planner)
    if not movements:
        raise CheckFailure("the planner proposed no movement at all")
    outside = _outside(movements, DEFAULT_SCENE.region.to_region(), 0.01)
    if outside:
        raise CheckFailure(outside)


class FixedMap(KitMap):
    """A stand-in map that reports one mean and std everywhere and ignores updates."""

    def __init__(self, mean: float, std: float, region: Region | None = None) -> None:
        super().__init__(region)
        self.level = (mean, std)

    def update(self, observations: Observations) -> None:
        pass

    def _query(self, points_m: np.ndarray) -> MapEstimate:
        n = len(points_m)
        return MapEstimate(np.full(n, self.level[0]), np.full(n, self.level[1]))


#: A search region smaller than any planner's line spacing: 1 cm by 0.8 cm, around the
#: middle of the kit's object.
TINY_SCENE = DEFAULT_SCENE.model_copy(update={"region": RegionConfig(
    x_min_m=0.395, x_max_m=0.405, y_min_m=0.246, y_max_m=0.254)})


def _planner_cases() -> dict[str, tuple[Scene, Map | None]]:
    region = DEFAULT_SCENE.region.to_region()
    return {
        "an all-unknown map (0.5 everywhere)": (DEFAULT_SCENE, FixedMap(0.5, 0.5, region)),
        "an all-occupied map (1.0 everywhere)": (DEFAULT_SCENE, FixedMap(1.0, 0.0, region)),
        "a 1 x 0.8 cm search region (smaller than one line spacing)": (TINY_SCENE, None),
    }


@check(Kind.PLANNER)
def check_planner_extremes(spec: PluginSpec, *, registry: Registry | None = None) -> None:
    """All-unknown and all-occupied maps and a tiny region: a finite search or a clear error.

    Each case runs an episode as :func:`planner_episode` does (at most ``max_movements``
    proposals, so a planner that never stops fails instead of hanging the kit). Movements
    must be finite and inside the region; a ``ValueError`` with a message (at build or
    while proposing) is an acceptable answer. The region comes from the kit's scene and
    stand-in map, so a ``check_config`` that sets its own region overrides the tiny one.
    """
    for what, (scene, the_map) in _planner_cases().items():
        try:
            planner = make_component(
                spec, registry=registry, scene=scene, planner_map=the_map, interface=Planner)
        except ValueError as exc:
            if str(exc) and not raised_by_record_validation(exc):
                continue  # refused at build: a clear error
            raise _invalid(spec, f"{what} (building)", exc) from exc
        try:
            movements = planner_episode(planner, scene)
        except CheckFailure as exc:
            raise CheckFailure(f"on {what}: {exc}") from exc
        except ValueError as exc:
            if str(exc) and not raised_by_record_validation(exc):
                continue
            raise _invalid(spec, what, exc) from exc
        except Exception as exc:
            raise _invalid(spec, what, exc) from exc
        finally:
            release_component(planner)
        region = scene.region.to_region()
        outside = _outside(movements, region, min(0.01, 0.1 * float(min(region.size_m))))
        if outside:
            raise CheckFailure(f"on {what}: {outside}")


# --- robots ----------------------------------------------------------------------------------


def _robot_states(robot: Robot, movement: ExploratoryMovement) -> list[RobotState]:
    try:
        return robot.execute(movement, max_steps=200_000)
    except RuntimeError as exc:
        raise CheckFailure(str(exc)) from exc


@check(Kind.ROBOT)
def check_robot_contract(spec: PluginSpec, *, registry: Registry | None = None) -> None:
    """Movements start at their start, advance at about the commanded speed, times increase."""
    robot = make_component(spec, registry=registry, interface=Robot)
    try:
        movement = crossing_movement(DEFAULT_SCENE)
        states = _robot_states(robot, movement)
        if not states:
            raise CheckFailure("execute() returned no states for a 0.7 m movement")
        t = np.array([s.timestamp_s for s in states])
        if np.any(np.diff(t) <= 0):
            raise CheckFailure("state timestamps are not strictly increasing")
        pos = np.vstack([s.position_m for s in states])
        if not np.all(np.isfinite(pos)):
            raise CheckFailure("states contain NaN positions")
        if np.linalg.norm(pos[0] - movement.start_m) > 0.01:
            raise CheckFailure(
                f"the first state {pos[0].tolist()} is not at the start "
                f"{movement.start_m.tolist()}"
            )
        step_max = movement.speed_m_per_s / robot.control_rate_hz * 1.5 + 1e-9
        if len(pos) > 1 and np.max(np.linalg.norm(np.diff(pos, axis=0), axis=1)) > step_max:
            raise CheckFailure("the fingertip moves faster than the commanded speed")
        if not robot.halt_reason and np.linalg.norm(pos[-1] - movement.end_m) > 0.01:
            raise CheckFailure("the movement ended early without a halt_reason")
        again = _robot_states(robot, movement)
        if again and again[0].timestamp_s <= t[-1]:
            raise CheckFailure("timestamps restart in the next movement; they must keep increasing")
    finally:
        release_component(robot)


@check(Kind.ROBOT)
def check_robot_halt(spec: PluginSpec, *, registry: Registry | None = None) -> None:
    """``halt()`` ends the movement at once."""
    robot = make_component(spec, registry=registry, interface=Robot)
    try:
        robot.begin(crossing_movement(DEFAULT_SCENE))
        for _ in range(3):
            robot.step()
        robot.halt("kit")
        if robot.step() is not None:
            raise CheckFailure("step() returned a state after halt(); it must return None")
    finally:
        release_component(robot)


def _inside_movement(robot: Robot) -> ExploratoryMovement:
    """The kit's crossing movement, or for a robot that declares a workspace, a movement
    across the middle of it."""
    region = robot.workspace
    if region is None:
        return crossing_movement(DEFAULT_SCENE)
    center, (width, _) = region.center_m, region.size_m
    half = np.array([0.4 * width, 0.0])
    return ExploratoryMovement(center - half, center + half, 0.05, phase="kit",
                               label="kit crossing")


@check(Kind.ROBOT)
def check_robot_stops_at_once(spec: PluginSpec, *, registry: Registry | None = None) -> None:
    """After ``halt()`` no command follows: every later ``step()`` returns None and the
    fingertip stays where it stopped, whether the halt comes before the first step or
    mid-movement (what the run's force limit, an interrupt and a device failure rely on)."""
    robot = make_component(spec, registry=registry, interface=Robot)
    try:
        movement = _inside_movement(robot)
        robot.begin(movement)
        robot.halt("kit")
        if robot.step() is not None:
            raise CheckFailure(
                "step() returned a state after a halt() that came right after begin(): a halt "
                "must stop the robot before its first command too"
            )
        robot.begin(movement)
        last: RobotState | None = None
        for _ in range(5):
            state = robot.step()
            if state is not None:
                last = state
        robot.halt("kit")
        for attempt in range(1, 4):
            if robot.step() is not None:
                raise CheckFailure(
                    f"step() returned a state {attempt} call(s) after halt(): no command may "
                    "follow a halt"
                )
        if last is not None:
            moved = float(np.linalg.norm(robot.state.position_m - last.position_m))
            if not moved <= 1e-9:
                raise CheckFailure(f"the fingertip moved {moved:.3g} m after halt()")
    finally:
        release_component(robot)


@check(Kind.ROBOT)
def check_robot_refuses_outside_workspace(
    spec: PluginSpec, *, registry: Registry | None = None
) -> None:
    """A robot that declares a ``workspace`` refuses a movement that leaves it or starts
    outside it: ``begin()`` raises ``ValueError`` with a message, so that even a direct
    caller cannot move there, and no step follows; a movement inside it still runs. (A
    robot that declares none passes.)"""
    robot = make_component(spec, registry=registry, interface=Robot)
    try:
        region = robot.workspace
        if region is None:
            return
        if not isinstance(region, Region):
            raise CheckFailure(
                f"workspace is a {type(region).__name__}; it must be a hapticframe.kinds.Region "
                "or None"
            )
        center = region.center_m
        width, height = region.size_m
        beyond_x = region.x_max_m + 0.1 * width + 0.01
        before_x = region.x_min_m - 0.1 * width - 0.01
        bounds = (f"x {region.x_min_m:g}...{region.x_max_m:g} m, "
                  f"y {region.y_min_m:g}...{region.y_max_m:g} m")
        cy = float(center[1])
        cases: dict[str, tuple[ArrayLike, ArrayLike]] = {
            "a movement that ends outside the workspace": (center, (beyond_x, cy)),
            "a movement that starts outside the workspace": ((before_x, cy), center),
            "a movement that leaves it across y": (
                center, (float(center[0]), region.y_max_m + 0.1 * height + 0.01)),
        }
        for what, (start, end) in cases.items():
            movement = ExploratoryMovement(
                np.asarray(start, dtype=np.float64), np.asarray(end, dtype=np.float64), 0.05,
                phase="kit", label="kit")
            if _refused(robot, spec, what, movement):
                continue
            raise CheckFailure(
                f"begin() accepted {what} ({bounds}): a robot that declares a workspace must "
                "raise ValueError, so that even a direct caller cannot move there"
            )
        states = _robot_states(robot, _inside_movement(robot))
        if not states:
            raise CheckFailure("a movement inside the workspace gave no states")
    finally:
        release_component(robot)


def _refused(robot: Robot, spec: PluginSpec, what: str, movement: ExploratoryMovement) -> bool:
    """Whether ``begin(movement)`` refused it with a ValueError of the robot's own (and no
    step followed); a movement it accepted is halted at once."""
    try:
        robot.begin(movement)
    except ValueError as exc:
        if not str(exc) or raised_by_record_validation(exc):
            raise _invalid(spec, what, exc) from exc
        if robot.step() is not None:
            raise CheckFailure(
                f"begin() refused {what}, but step() then returned a state") from None
        return True
    robot.halt("kit")
    return False


@check(Kind.ROBOT)
def check_robot_refuses_bad_depth(spec: PluginSpec, *, registry: Registry | None = None) -> None:
    """``begin()`` refuses a movement whose depth is zero, negative or NaN with a
    ``ValueError``, and no step follows. ``Robot.begin`` does this before it calls the
    plugin's ``_begin``: a robot that overrides ``begin`` itself must too."""
    robot = make_component(spec, registry=registry, interface=Robot)
    try:
        inside = _inside_movement(robot)
        for what, depth in (("a negative depth", -0.01), ("a zero depth", 0.0),
                            ("a NaN depth", math.nan)):
            movement = dataclasses.replace(inside, depth_m=depth)
            if _refused(robot, spec, what, movement):
                continue
            raise CheckFailure(
                f"begin() accepted {what} ({depth} m): it must raise ValueError; implement "
                "Robot._begin and leave the checks to Robot.begin"
            )
    finally:
        release_component(robot)


def _robot_cases() -> dict[str, tuple[ExploratoryMovement, int]]:
    """Extreme movements, each with how many steps it may take at most (beyond its length)."""
    region = DEFAULT_SCENE.region.to_region()
    inside = region.center_m + np.array([0.2, 0.0])
    beyond = np.array([region.x_max_m + 0.25, region.y_max_m + 0.15])
    far = beyond + 1.0
    return {
        "a zero-length movement": (ExploratoryMovement(inside, inside, 0.05, label="kit"), 10),
        "a movement that leaves the workspace": (
            ExploratoryMovement(inside, beyond, 0.1, label="kit"), 50),
        "a movement wholly outside the workspace": (
            ExploratoryMovement(far, far + np.array([0.05, 0.0]), 0.1, label="kit"), 50),
    }


@check(Kind.ROBOT)
def check_robot_extremes(spec: PluginSpec, *, registry: Registry | None = None) -> None:
    """Zero-length and out-of-workspace movements: a finite result or a clear error.

    Each movement either raises a ``ValueError`` with a message or runs to its end within
    its length's worth of steps (plus a margin) with finite states and increasing times;
    afterwards the robot still runs an ordinary movement with times that keep increasing.
    """
    robot = make_component(spec, registry=registry, interface=Robot)
    last_t = -np.inf
    try:
        for what, (movement, margin) in _robot_cases().items():
            duration_s = movement.length_m / movement.speed_m_per_s
            budget = int(duration_s * robot.control_rate_hz) + margin
            try:
                states = robot.execute(movement, max_steps=budget)
            except ValueError as exc:
                if str(exc) and not raised_by_record_validation(exc):
                    continue  # refused: a clear error
                raise _invalid(spec, what, exc) from exc
            except RuntimeError as exc:
                raise CheckFailure(
                    f"{what} did not end within {budget} steps: {exc}") from exc
            except Exception as exc:
                raise _invalid(spec, what, exc) from exc
            last_t = _check_states(states, robot, what, last_t)
        ordinary = crossing_movement(DEFAULT_SCENE)
        states = _robot_states(robot, ordinary)
        if not states:
            raise CheckFailure("after the extreme movements an ordinary movement gave no states")
        _check_states(states, robot, "an ordinary movement after the extreme ones", last_t)
    finally:
        release_component(robot)


def _check_states(states: list[RobotState], robot: Robot, what: str, last_t: float) -> float:
    """Fail on NaN or non-increasing times in ``states``; returns the last time."""
    if states:
        t = np.array([s.timestamp_s for s in states])
        pos = np.vstack([s.position_m for s in states])
        if not (np.all(np.isfinite(t)) and np.all(np.isfinite(pos))):
            raise CheckFailure(f"{what} gave states with NaN or infinite times or positions")
        if t[0] <= last_t or np.any(np.diff(t) <= 0):
            raise CheckFailure(f"{what} gave state times that do not keep increasing")
        last_t = float(t[-1])
    final = robot.state
    if not (np.isfinite(final.timestamp_s) and np.all(np.isfinite(final.position_m))):
        raise CheckFailure(f"after {what} the robot's state is not finite: {final}")
    return last_t


# --- determinism -----------------------------------------------------------------------------


def _exercise(
    spec: PluginSpec, registry: Registry | None, config: Mapping[str, Any] | None = None
) -> list[Any]:
    """Build ``spec`` (with ``config``, default its check config) and drive it as its kind
    is driven; the outputs."""
    # Built as the interface of its kind, so the branches below follow spec.kind.
    component = make_component(spec, registry=registry, seed=11, config=config,
                               interface=INTERFACES[spec.kind])
    try:
        if isinstance(component, Sensor):
            return sensor_outputs(component, spec)
        if isinstance(component, (FeatureExtractor, Classifier)):
            return exercise_stream(component, spec)
        if isinstance(component, SensorModel):
            obs = component.observe(located_measurement())
            return [obs.points_m, obs.targets, obs.weights]
        if isinstance(component, Map):
            component.update(map_observations(9))
            est = component.query(_query_grid(component))
            return [est.mean, est.std]
        if isinstance(component, Planner):
            return [(m.start_m, m.end_m, m.phase) for m in planner_episode(component)]
        if isinstance(component, Robot):
            states = _robot_states(component, crossing_movement(DEFAULT_SCENE))
            return [
                np.array([s.timestamp_s for s in states]),
                np.vstack([s.position_m for s in states]),
            ]
        raise CheckFailure(f"{spec.kind} components are not exercised")  # pragma: no cover
    finally:
        release_component(component)


@check()
def check_deterministic(spec: PluginSpec, *, registry: Registry | None = None) -> None:
    """Two components built with the same seed behave identically."""
    first = _exercise(spec, registry)
    second = _exercise(spec, registry)
    if not outputs_equal(first, second):
        raise CheckFailure(
            "two components built with the same seed gave different outputs: draw randomness "
            "from context.rng only, never from global state"
        )

