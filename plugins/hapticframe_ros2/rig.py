"""``python -m hapticframe_ros2.rig EXPERIMENT``: the emulated rig behind an experiment's topics.

Reads the experiment file, takes its scene, its seed, its ``ros2`` robot (domain, topics,
QoS) and its ``ros2-topic`` force sensor (the wrench topic), and serves the sandbox behind
them until interrupted (Ctrl-C). Start it before ``hapticframe run EXPERIMENT``::

    python -m hapticframe_ros2.rig examples/search-ros2.yaml &
    hapticframe run examples/search-ros2.yaml --out runs/ros2
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from ._rig import EmulatedRig

__all__ = ["main", "rig_for_experiment"]


def rig_for_experiment(path: str, *, domain_id: int | None = None) -> EmulatedRig:
    """The :class:`~hapticframe_ros2.EmulatedRig` behind the topics of the experiment at
    ``path`` (``domain_id`` overrides the robot's)."""
    from hapticframe import Kind, validate_file

    from ._config import Ros2RobotConfig, Ros2TopicSensorConfig
    from ._rig import EmulatedRig

    experiment = validate_file(path)
    robots = [e for e in experiment.of_kind(Kind.ROBOT) if e.type == "ros2"]
    sensors = [e for e in experiment.of_kind(Kind.SENSOR) if e.type == "ros2-topic"]
    if len(robots) != 1 or experiment.model.scene is None:
        raise ValueError(f"{path}: the rig serves an experiment with one robot of type 'ros2' "
                         "and a scene")
    robot = robots[0]
    cfg = robot.config
    assert isinstance(cfg, Ros2RobotConfig)
    wrench_topic, sensor_id = cfg.wrench_topic, "wrist"
    for entry in sensors:
        sensor_cfg = entry.config
        assert isinstance(sensor_cfg, Ros2TopicSensorConfig)
        if sensor_cfg.message == "geometry_msgs/msg/WrenchStamped":
            wrench_topic, sensor_id = sensor_cfg.topic, entry.id
            break
    return EmulatedRig(
        experiment.model.scene, domain_id=cfg.domain_id if domain_id is None else domain_id,
        seed=experiment.seed, robot_id=robot.id, sensor_id=sensor_id,
        goal_topic=cfg.goal_topic, setpoint_topic=cfg.setpoint_topic,
        pose_topic=cfg.pose_topic, wrench_topic=wrench_topic, qos=cfg.qos)


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m hapticframe_ros2.rig",
                                     description=__doc__.splitlines()[0])
    parser.add_argument("experiment")
    parser.add_argument("--domain-id", type=int, default=None)
    args = parser.parse_args(argv)
    from ._dds import require_dds

    try:
        require_dds("the emulated rig")
        rig = rig_for_experiment(args.experiment, domain_id=args.domain_id)
    except Exception as exc:  # a located message, not a traceback
        print(f"error: {exc}", file=sys.stderr)
        return 2
    print(f"emulated rig serving {args.experiment} (Ctrl-C stops it)", flush=True)
    try:
        rig.serve_forever()
    except KeyboardInterrupt:
        pass
    finally:
        rig.stop()
    return 0


if __name__ == "__main__":
    sys.exit(main())
