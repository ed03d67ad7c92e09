"""The behavioural interfaces of the seven plugin kinds and the records they exchange.

One module per kind states its contract; the data records are shared. Data flows one way:
sensor → feature extractor → classifier → sensor model → map → planner → robot.
What only some components can do (train, persist, evaluate on a grid) is declared in
:mod:`hapticframe.kinds.capabilities`.
"""

from ._base import OUTLINE_LEVEL, BuildContext, Component, InputAlignment, RunOutcome
from ._records import (
    ChannelInfo,
    ClassProbabilities,
    ExploratoryMovement,
    LocatedMeasurement,
    MapEstimate,
    MovementResult,
    Observations,
    PhysicalTruth,
    Region,
    RobotState,
    SampleBatch,
    concatenate_batches,
)
from .capabilities import (
    Device,
    EnvironmentCoupled,
    GridQueryable,
    Persistent,
    PhysicalTruthSource,
    RobotFollower,
    Trainable,
)
from .classifier import Classifier
from .feature_extractor import FeatureExtractor
from .map import Map, query_points
from .planner import Planner
from .robot import Robot
from .sensor import Sensor
from .sensor_model import SensorModel

__all__ = [
    "BuildContext",
    "ChannelInfo",
    "ClassProbabilities",
    "Classifier",
    "Component",
    "Device",
    "EnvironmentCoupled",
    "ExploratoryMovement",
    "FeatureExtractor",
    "GridQueryable",
    "InputAlignment",
    "LocatedMeasurement",
    "Map",
    "MapEstimate",
    "MovementResult",
    "OUTLINE_LEVEL",
    "Observations",
    "Persistent",
    "PhysicalTruth",
    "PhysicalTruthSource",
    "Planner",
    "Region",
    "Robot",
    "RobotFollower",
    "RobotState",
    "RunOutcome",
    "SampleBatch",
    "Sensor",
    "SensorModel",
    "Trainable",
    "concatenate_batches",
    "query_points",
]
