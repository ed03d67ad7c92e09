"""The ``mpm-sand`` world: forces from an engine's response library, behind the sandbox's plumbing.

:class:`MpmSandWorld` is a :class:`hapticframe.kinds.World` whose per-step force comes from a
:class:`~hapticframe_mpm_sand.ResponseLibrary` instead of the failure-zone mechanics;
:class:`MpmSandRobot` is the :class:`hapticframe_sandbox.SandboxRobot` (movements, depth
schedule, ground truth, ``follows``, the ``sandbox-force`` sensor) that holds it, chosen by
its public :meth:`~hapticframe_sandbox.SandboxRobot.build_world`:

- free drag: the library's engine drag at the movement's depth and the plate's travel
  (start-up included), times a slow random fluctuation;
- a buried object whose outline the library has shape tables for (an ellipse or a box run
  in the engine at yaws of 0–90°) is met as itself: the table's force ratio at (depth, the
  object's yaw to the heading, signed lateral offset / (its half-extent across the heading
  + plate half-width), plate front − its foremost point) adds its excess over 1 (x and y);
- any other object is met as its *equivalent cylinder*: radius the object's half-extent
  across the heading, centred on that extent, leading point the object's foremost point
  along the heading; the library's cylinder ratio at (depth, radius, |lateral offset| /
  (radius + plate half-width), plate front − leading point) adds its excess;
- the engine adds no contact force (its bodies only follow paths), so the world does: a
  spring on the distance the plate's face has gone past the object's outline within its
  band (``contact_stiffness_n_per_m``).

Ground truth labels a step *jamming* when the library's x ratio reaches
``jamming_label_ratio`` (10 % above free drag by default: the engine's account, not the
failure-zone model's), *contact* while the plate touches.
"""

from __future__ import annotations

import math
from importlib import resources
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from hapticframe import Scene
from hapticframe.kinds import (
    BuildContext,
    PlateMovement,
    PlateSample,
    TruthState,
    World,
    WorldResponse,
)
from hapticframe_sandbox import SandboxRobot

from ._config import BUNDLED_LIBRARIES, MpmSandRobotConfig
from ._library import ResponseLibrary, load_library, material_parameters

__all__ = ["MpmSandRobot", "MpmSandWorld", "bundled_library"]

FREE, JAMMING, CONTACT = int(TruthState.FREE), int(TruthState.JAMMING), int(TruthState.CONTACT)
_LIBRARIES: dict[str, ResponseLibrary] = {}


def bundled_library(voxel_size_m: float = 0.0075) -> ResponseLibrary:
    """The library shipped with the plugin for ``voxel_size_m`` (cached after the first load)."""
    name = next((n for v, n in BUNDLED_LIBRARIES.items() if math.isclose(v, voxel_size_m)), None)
    if name is None:
        sizes = ", ".join(f"{v:g}" for v in BUNDLED_LIBRARIES)
        raise ValueError(f"no bundled response library at voxel_size_m {voxel_size_m:g} "
                         f"(bundled: {sizes}); build one and set library_path")
    path = Path(str(resources.files("hapticframe_mpm_sand") / "data" / name))
    return _cached(path)


def _cached(path: Path) -> ResponseLibrary:
    key = str(path.resolve())
    if key not in _LIBRARIES:
        _LIBRARIES[key] = load_library(path)
    return _LIBRARIES[key]


def check_material(
    robot_id: str, library: ResponseLibrary, friction_angle_deg: float, dilation_angle_deg: float
) -> None:
    """Refuse a scene whose sand is not the library's (its friction and dilatancy)."""
    friction, dilatancy = material_parameters(friction_angle_deg, dilation_angle_deg)
    built_friction, built_dilatancy = float(library.settings[4]), float(library.settings[5])
    if abs(friction - built_friction) > 0.005 or abs(dilatancy - built_dilatancy) > 0.005:
        phi = math.degrees(math.atan(built_friction))
        psi = math.degrees(math.atan(built_dilatancy * built_friction))
        raise ValueError(
            f"robot {robot_id!r} (type 'mpm-sand'): its response library was built for sand "
            f"of friction angle {phi:.1f} deg and dilation angle {psi:.1f} deg; the scene's is "
            f"{friction_angle_deg:g} and {dilation_angle_deg:g} deg. Build a library for it "
            f"(python -m hapticframe_mpm_sand.build_library --friction-angle-deg "
            f"{friction_angle_deg:g} --dilation-angle-deg {dilation_angle_deg:g} --out FILE) "
            "and set library_path"
        )


class MpmSandWorld(World):
    """The plate's force from the engine's response library, the contact spring added.

    Parameters
    ----------
    config : MpmSandRobotConfig
        ``drag_fluctuation_*``, ``offset_taper_u``, ``jamming_label_ratio`` and
        ``contact_stiffness_n_per_m`` are used.
    scene : Scene
        The buried objects (their outlines) and the sand (checked against the library's).
    rng : numpy.random.Generator
        Source of the drag fluctuation.
    library : ResponseLibrary
        The engine runs the forces are interpolated from.
    world_id : str
        Named in errors (the robot's id).
    """

    def __init__(self, config: MpmSandRobotConfig, scene: Scene, rng: np.random.Generator,
                 library: ResponseLibrary, world_id: str = "mpm-sand") -> None:
        check_material(world_id, library, scene.material.friction_angle_deg,
                       scene.material.dilation_angle_deg)
        self.config = config
        self.library = library
        self._rng = rng
        self._outlines = [np.asarray(obj.outline(512), dtype=np.float64) for obj in scene.objects]
        # Which objects the library's shape tables describe: (table, yaw of the table's
        # outline in the map frame), or None for an equivalent cylinder.
        self._shapes: list[tuple[int, float] | None] = []
        for obj, outline in zip(scene.objects, self._outlines, strict=True):
            turn = math.radians(obj.orientation_deg)
            rotation = np.array([[math.cos(turn), math.sin(turn)],
                                 [-math.sin(turn), math.cos(turn)]])
            local = (outline - np.asarray(obj.center_m)) @ rotation.T
            match = library.match_shape(local) if library.shape_count else None
            self._shapes.append(None if match is None
                                else (match[0], obj.orientation_deg + match[1]))

    @property
    def shape_tables(self) -> list[int | None]:
        """Per scene object, the library shape table it is met by (None: its equivalent
        cylinder)."""
        return [None if match is None else match[0] for match in self._shapes]

    def begin(self, movement: PlateMovement) -> None:
        cfg, rng = self.config, self._rng
        self._movement = movement
        self._decay = math.exp(-movement.control_period_s / cfg.drag_fluctuation_time_s)
        self._innovation = math.sqrt(1 - self._decay * self._decay)
        # Three draws that the analytic world spends on its shear-band cycle: spent here too,
        # so that one seed gives both worlds the same drag fluctuation (and this world the
        # runs it gave before worlds were a seam of their own).
        rng.uniform(size=3)
        self._fluctuation = cfg.drag_fluctuation_fraction * rng.standard_normal()
        # Each object's outline in the movement's frame: along the heading from the start,
        # and across it (+ to the left).
        dx, dy = movement.direction
        sx, sy = movement.start_m
        self._heading_deg = math.degrees(math.atan2(dy, dx))
        frames = []
        for outline in self._outlines:
            rx, ry = outline[:, 0] - sx, outline[:, 1] - sy
            frames.append((rx * dx + ry * dy, -rx * dy + ry * dx))
        self._frames: list[tuple[NDArray[np.float64], NDArray[np.float64]]] = frames

    def respond(self, plate: PlateSample) -> WorldResponse:
        cfg, movement = self.config, self._movement
        library = self.library
        self._fluctuation = self._decay * self._fluctuation + self._innovation * (
            cfg.drag_fluctuation_fraction * self._rng.standard_normal()
        )
        scale = max(0.0, 1.0 + self._fluctuation)
        depth = movement.depth_m
        drag = library.free_drag(depth, plate.travelled_m) * scale
        dx, dy = movement.direction
        sx, sy = movement.start_m
        position = plate.position_m
        along = (position[0] - sx) * dx + (position[1] - sy) * dy
        across = -(position[0] - sx) * dy + (position[1] - sy) * dx
        half = movement.plate_width_m / 2
        u_max = float(library.offsets_u[-1])
        shape_u_max = float(library.shape_offsets_u[-1]) if library.shape_count else 0.0
        excess_x = excess_y = 0.0
        penetration = 0.0
        # An object adds to the drag, never takes from it: the library's ratios below 1
        # (down to 0.72, far to the side) come from object runs in a wider bed than the free
        # run's (docs/physics-world.md), not from the sand.
        for (a, c), shape in zip(self._frames, self._shapes, strict=True):
            s_m = along - float(a.min())
            if along > float(a.max()) or s_m < float(library.s_m[0]):
                continue  # past the object, or farther ahead than any engine run saw it
            c_low, c_high = float(c.min()), float(c.max())
            radius = (c_high - c_low) / 2
            offset = across - (c_low + c_high) / 2
            u = abs(offset) / (radius + half)
            if shape is not None:
                # The tables' offset is signed, + with the object on the plate's left.
                taper = 1.0 - max(0.0, u - shape_u_max) / cfg.offset_taper_u
                if taper > 0.0:
                    signed_u = math.copysign(min(u, shape_u_max), -offset)
                    rx, ry = library.shape_ratio(depth, shape[0], shape[1] - self._heading_deg,
                                                 signed_u, min(0.0, s_m))
                    excess_x += max(0.0, rx - 1.0) * taper
                    excess_y += ry * taper
            else:
                taper = 1.0 - max(0.0, u - u_max) / cfg.offset_taper_u
                if taper > 0.0:
                    rx, ry = library.ratio(depth, radius, min(u, u_max), min(0.0, s_m))
                    excess_x += max(0.0, rx - 1.0) * taper
                    # ratio_y is for an object on the +across side; mirror for the other side.
                    excess_y += ry * taper * (1.0 if offset <= 0 else -1.0)
            band = np.abs(c - across) <= half
            if band.any():
                front = float(a[band].min())
                if front <= along <= float(a[band].max()):
                    penetration = max(penetration, along - front)
        ratio_x = 1.0 + excess_x
        # Force on the plate: against the heading (x ratio), across it (y ratio).
        fx = -drag * (ratio_x * dx - excess_y * dy)
        fy = -drag * (ratio_x * dy + excess_y * dx)
        state = JAMMING if ratio_x >= cfg.jamming_label_ratio else FREE
        if penetration > 0.0:
            state = CONTACT
            spring = cfg.contact_stiffness_n_per_m * penetration
            fx, fy = fx - spring * dx, fy - spring * dy
        return WorldResponse((fx, fy), state)


class MpmSandRobot(SandboxRobot):
    """A plate raked through sand, its force from the engine's response library: the
    sandbox robot holding an :class:`MpmSandWorld`.

    Parameters
    ----------
    config : MpmSandRobotConfig
    context : BuildContext
        Needs ``context.scene``; randomness (the drag fluctuation) from ``context.rng``.
    """

    config: MpmSandRobotConfig

    def __init__(self, config: MpmSandRobotConfig, context: BuildContext) -> None:
        self._library = (
            bundled_library(config.voxel_size_m)
            if config.library_path is None
            else _cached(Path(config.library_path))
        )
        super().__init__(config, context)

    def build_world(self, scene: Scene, rng: np.random.Generator) -> World:
        """An :class:`MpmSandWorld` on this robot's library."""
        return MpmSandWorld(self.config, scene, rng, self._library, self.id)

    @property
    def library(self) -> ResponseLibrary:
        """The response library the forces come from."""
        return self._library
