"""Registration of the ``mpm-sand`` world and its benchmark (import-light: no engine)."""

from __future__ import annotations

from collections.abc import Iterator

from hapticframe import BenchSpec, Kind, Knob, RobotSpec, hookimpl

from ._config import MpmSandRobotConfig

_HINT = "pip install 'hapticframe[physics]'  (NVIDIA Newton on Warp, about 480 MB)"


@hookimpl
def hapticframe_robots() -> Iterator[RobotSpec]:
    yield RobotSpec(
        name="mpm-sand",
        summary="Plate raked through sand simulated by NVIDIA Newton's material-point solver "
        "(a response library of engine runs), the contact force added after touch.",
        config=MpmSandRobotConfig,
        factory="hapticframe_mpm_sand._world:MpmSandRobot",
        capabilities=frozenset({"simulated"}),
        knobs=(
            Knob("voxel_size_m", "the engine's grid cell the library was built at: finer is "
                 "closer to a converged drag, costs more to build (not to run)",
                 values=(0.0075, 0.01)),
            Knob("control_rate_hz", "more control steps per second: finer force timing, more "
                 "steps per movement", values=(50.0, 100.0, 200.0)),
        ),
        inputs=(Kind.ROBOT,),
    )


@hookimpl
def hapticframe_benchmarks() -> Iterator[BenchSpec]:
    yield BenchSpec(
        name="physics-checks",
        summary="The engine's two physical checks (issue 29): free drag against depth "
        "(power-law exponent) and the force rise ahead of a buried cylinder.",
        factory="hapticframe_mpm_sand._checks:run_physics_checks",
        install_hint=_HINT,
    )
