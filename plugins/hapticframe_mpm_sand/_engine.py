"""One raking run in NVIDIA Newton's implicit material-point solver (the ``physics`` extra).

A rectangular bed of sand particles (Drucker–Prager: friction, dilatancy; no cohesion) in a
box; a thin vertical plate, kinematic, raked along +x at constant speed and depth; optionally
a buried vertical prism (kinematic, held still) ahead of it: a cylinder, or an elliptic or
rectangular prism at a yaw to the raking direction. Each step the impulses the
solver applied at the plate's collider are summed into the sand's force on the plate. The
engine models no contact between the two kinematic bodies: once the plate reaches the
object the sand squeezes out, and the world adds the contact force itself.

Frame: x along the raking, y across, z up; the sand's free surface at ``z = bed_height_m``.
This module is the only one that imports ``newton`` and ``warp``; nothing imports it unless
an engine run is asked for.
"""

from __future__ import annotations

import dataclasses
import math
import time

import numpy as np
from numpy.typing import NDArray

__all__ = ["OBJECT_SHAPES", "EngineSettings", "RakeCase", "RakeResult", "engine_available",
           "object_footprint", "rake"]

#: The buried objects the engine can hold: vertical prisms of these cross-sections.
OBJECT_SHAPES = ("cylinder", "ellipse", "box")
#: Points on an ellipse's outline in its prism mesh (a 64-gon is within 0.1 % of its area).
_ELLIPSE_POINTS = 64


def engine_available() -> bool:
    """True when ``newton`` (and ``warp``) import: ``pip install 'hapticframe[physics]'``."""
    try:
        import newton  # noqa: F401
        import warp  # noqa: F401
    except ImportError:
        return False
    return True


@dataclasses.dataclass(frozen=True)
class EngineSettings:
    """Resolution and material of an engine run (the world's fidelity knobs)."""

    voxel_size_m: float = 0.0075
    particles_per_cell: float = 2.0
    step_s: float = 0.03
    max_iterations: int = 200
    #: tan φ of the examples' sand mixture (φ = 42°): Newton's Drucker–Prager |τ| ≤ μ p.
    friction_coefficient: float = 0.9004
    #: Newton's plastic volumetric rate is ``dilatancy · μ`` times the shear rate; tan ψ / tan φ
    #: with ψ = 12° makes it tan ψ.
    dilatancy: float = 0.2360
    bulk_density_kg_per_m3: float = 1600.0
    bed_length_m: float = 0.12
    bed_width_m: float = 0.09
    bed_height_m: float = 0.06
    #: The plate's centre line (y); off-centre so that objects beside it fit in the bed.
    plate_line_y_m: float = 0.035


@dataclasses.dataclass(frozen=True)
class RakeCase:
    """One movement: plate at ``depth_m`` from ``start_x_m`` for ``travel_m`` at ``speed``.

    ``object_radius_m`` 0 (with ``object_shape`` "cylinder") means free sand; otherwise a
    vertical prism from the floor to ``object_top_below_surface_m`` under the surface, its
    axis at ``(object_x_m, lateral_offset_m)`` (the plate's centre line is y = 0): a cylinder
    of ``object_radius_m``, or an ``ellipse`` (semi-axes) or ``box`` (half-sides) of
    ``object_half_extents_m`` along its own x and y, its x at ``object_yaw_deg`` to the
    raking direction (counter-clockwise).
    """

    depth_m: float = 0.04
    plate_width_m: float = 0.02
    plate_thickness_m: float = 0.005
    speed_m_per_s: float = 0.05
    start_x_m: float = 0.02
    travel_m: float = 0.055
    object_radius_m: float = 0.0
    object_x_m: float = 0.09
    lateral_offset_m: float = 0.0
    object_top_below_surface_m: float = 0.005
    object_shape: str = "cylinder"
    object_half_extents_m: tuple[float, float] = (0.0, 0.0)
    object_yaw_deg: float = 0.0

    def __post_init__(self) -> None:
        if self.object_shape not in OBJECT_SHAPES:
            raise ValueError(f"object_shape {self.object_shape!r}: one of "
                             f"{', '.join(OBJECT_SHAPES)}")
        if self.object_shape != "cylinder" and min(self.object_half_extents_m) <= 0:
            raise ValueError(f"a {self.object_shape} needs positive object_half_extents_m, "
                             f"not {self.object_half_extents_m}")

    @property
    def has_object(self) -> bool:
        """False for free sand."""
        return self.object_shape != "cylinder" or self.object_radius_m > 0


def object_footprint(case: RakeCase, points: int = _ELLIPSE_POINTS) -> NDArray[np.float64]:
    """The object's outline about its axis, in the rake's frame (x along the raking): an
    ``(n, 2)`` array, counter-clockwise (a box gives its four corners)."""
    if case.object_shape == "cylinder":
        t = np.linspace(0, 2 * np.pi, points, endpoint=False)
        return case.object_radius_m * np.column_stack([np.cos(t), np.sin(t)])
    a, b = case.object_half_extents_m
    if case.object_shape == "ellipse":
        t = np.linspace(0, 2 * np.pi, points, endpoint=False)
        local = np.column_stack([a * np.cos(t), b * np.sin(t)])
    else:
        local = np.array([[a, b], [-a, b], [-a, -b], [a, -b]], dtype=np.float64)
    yaw = math.radians(case.object_yaw_deg)
    rotation = np.array([[math.cos(yaw), -math.sin(yaw)], [math.sin(yaw), math.cos(yaw)]])
    return np.asarray(local @ rotation.T, dtype=np.float64)


def _inside_footprint(xy: NDArray[np.float64], outline: NDArray[np.float64]
                      ) -> NDArray[np.bool_]:
    """Points inside a convex, counter-clockwise outline (edges' left sides)."""
    inside = np.ones(len(xy), dtype=bool)
    for p, q in zip(outline, np.roll(outline, -1, axis=0), strict=True):
        edge = q - p
        inside &= edge[0] * (xy[:, 1] - p[1]) - edge[1] * (xy[:, 0] - p[0]) >= 0
    return inside


def _prism_mesh(outline: NDArray[np.float64], height: float
                ) -> tuple[NDArray[np.float64], NDArray[np.int32]]:
    """Vertices and triangles of a vertical prism over a convex outline, z in [-h/2, h/2]
    about its centre (caps fanned from the axis, outward normals)."""
    n = len(outline)
    half = height / 2
    ring = np.vstack([np.column_stack([outline, np.full(n, -half)]),
                      np.column_stack([outline, np.full(n, half)])])
    vertices = np.vstack([ring, [[0.0, 0.0, -half], [0.0, 0.0, half]]])
    bottom, top = 2 * n, 2 * n + 1
    faces = []
    for i in range(n):
        j = (i + 1) % n
        faces += [(i, j, n + j), (i, n + j, n + i),  # side
                  (bottom, j, i), (top, n + i, n + j)]  # caps
    return vertices, np.asarray(faces, dtype=np.int32).reshape(-1)


@dataclasses.dataclass(frozen=True)
class RakeResult:
    """Per step: plate front position ``x_m`` and the sand's force on the plate (N)."""

    x_m: NDArray[np.float64]
    force_n: NDArray[np.float64]  # (n, 3): x, y, z
    particle_count: int
    cpu_s: float
    wall_s: float


def rake(case: RakeCase, settings: EngineSettings, seed: int = 0) -> RakeResult:
    """Run one movement in the engine; ``seed`` sets the particles' initial jitter."""
    import newton
    import warp as wp
    from newton.solvers import SolverImplicitMPM

    wp.config.quiet = True
    wp.init()
    s, c = settings, case
    builder = newton.ModelBuilder()
    SolverImplicitMPM.register_custom_attributes(builder)
    y0 = s.plate_line_y_m
    axis_y = y0 + c.lateral_offset_m
    # The bed reaches at least a cell past the object's axis across the plate, so that an
    # object far to the side is met in sand, not in the wall.
    width = max(s.bed_width_m, axis_y + 2 * s.voxel_size_m if c.has_object else 0.0)
    # And at least 4.5 cm past the end of the travel (a longer run gets a longer bed).
    length = max(s.bed_length_m, c.start_x_m + c.travel_m + 0.045)
    # The box: floor and four walls (static shapes).
    builder.add_ground_plane()
    wall = 0.01
    half_l, half_w, h = length / 2, width / 2, s.bed_height_m * 1.5
    for px, py, hx, hy in (
        (-wall, half_w, wall, half_w + 2 * wall),
        (length + wall, half_w, wall, half_w + 2 * wall),
        (half_l, -wall, half_l + 2 * wall, wall),
        (half_l, width + wall, half_l + 2 * wall, wall),
    ):
        builder.add_shape_box(-1, xform=wp.transform(wp.vec3(px, py, h / 2), wp.quat_identity()),
                              hx=hx, hy=hy, hz=h / 2)
    plate_half_h = (c.depth_m + 0.02) / 2
    plate_z = s.bed_height_m - c.depth_m + plate_half_h
    plate = builder.add_body(
        xform=wp.transform(wp.vec3(c.start_x_m - c.plate_thickness_m / 2, y0, plate_z),
                           wp.quat_identity()),
        is_kinematic=True,
    )
    builder.add_shape_box(plate, hx=c.plate_thickness_m / 2, hy=c.plate_width_m / 2,
                          hz=plate_half_h)
    footprint = object_footprint(c)
    if c.has_object:
        top = s.bed_height_m - c.object_top_below_surface_m
        body = builder.add_body(
            xform=wp.transform(wp.vec3(c.object_x_m, axis_y, top / 2), wp.quat_identity()),
            is_kinematic=True,
        )
        if c.object_shape == "cylinder":
            builder.add_shape_cylinder(body, radius=c.object_radius_m, half_height=top / 2)
        else:
            vertices, faces = _prism_mesh(footprint, top)
            builder.add_shape_mesh(body, mesh=newton.Mesh(vertices, faces,
                                                          compute_inertia=False))
    # The sand: a jittered grid of particles filling the box to the bed height, none inside
    # the plate or the object (the engine would expel them: a denser bed around them).
    rng = np.random.default_rng(seed)
    hi = np.array([length, width, s.bed_height_m])
    res = np.ceil(s.particles_per_cell ** (1 / 3) * hi / s.voxel_size_m).astype(int)
    cell = hi / res
    radius = float(np.max(cell) * 0.5)
    axes = [(np.arange(n) + 0.5) * size for n, size in zip(res, cell, strict=True)]
    points = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)
    points += (rng.random(points.shape) - 0.5) * cell
    plate_x = c.start_x_m - c.plate_thickness_m / 2
    inside = (
        (np.abs(points[:, 0] - plate_x) <= c.plate_thickness_m / 2)
        & (np.abs(points[:, 1] - y0) <= c.plate_width_m / 2)
        & (points[:, 2] >= s.bed_height_m - c.depth_m)
    )
    if c.has_object:
        relative = points[:, :2] - np.array([c.object_x_m, axis_y])
        within = (np.hypot(relative[:, 0], relative[:, 1]) <= c.object_radius_m
                  if c.object_shape == "cylinder" else _inside_footprint(relative, footprint))
        inside |= within & (
            points[:, 2] <= s.bed_height_m - c.object_top_below_surface_m)
    points = points[~inside]
    count = len(points)
    builder.add_particles(
        pos=[wp.vec3(*p) for p in points.tolist()],
        vel=[wp.vec3(0.0)] * count,
        mass=[float(np.prod(cell) * s.bulk_density_kg_per_m3)] * count,
        radius=[radius] * count,
        custom_attributes={"mpm:friction": [s.friction_coefficient] * count,
                           "mpm:dilatancy": [s.dilatancy] * count},
    )
    model = builder.finalize()
    options = SolverImplicitMPM.Config()
    options.voxel_size = s.voxel_size_m
    options.max_iterations = s.max_iterations
    options.grid_type = "sparse"
    solver = SolverImplicitMPM(model, config=options)
    state = model.state()
    dt = s.step_s
    n_steps = math.ceil(c.travel_m / (c.speed_m_per_s * dt))
    # Let the bed settle under gravity with the plate still, then rake.
    settle = max(2, round(0.1 / dt))
    assert state.body_q is not None and state.body_qd is not None
    body_q = state.body_q.numpy()
    body_qd = np.zeros_like(state.body_qd.numpy())
    xs = np.empty(n_steps)
    forces = np.empty((n_steps, 3))
    start_cpu, start_wall = time.process_time(), time.perf_counter()
    x0 = float(body_q[plate][0])
    for k in range(-settle, n_steps):
        moving = k >= 0
        x = x0 + (c.speed_m_per_s * dt * (k + 1) if moving else 0.0)
        body_q[plate][0] = x
        body_qd[plate][:] = 0.0
        # spatial_vector: linear part first in Newton 1.x
        body_qd[plate][0] = c.speed_m_per_s if moving else 0.0
        state.body_q.assign(body_q)
        state.body_qd.assign(body_qd)
        solver.step(state, state, None, None, dt)
        if moving:
            impulses, _pos, ids = solver.collect_collider_impulses(state)
            imp = impulses.numpy()
            cid = ids.numpy()
            plate_collider = int(np.nonzero(solver.collider_body_index.numpy() == plate)[0][0])
            forces[k] = imp[cid == plate_collider].sum(axis=0) / dt
            xs[k] = x + c.plate_thickness_m / 2
    return RakeResult(
        x_m=xs, force_n=forces, particle_count=int(model.particle_count),
        cpu_s=time.process_time() - start_cpu, wall_s=time.perf_counter() - start_wall,
    )
