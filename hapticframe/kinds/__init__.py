"""The behavioural interfaces of the seven plugin kinds and the records they exchange.

One module per kind states its contract; the data records are shared. Data flows one way:
sensor → feature extractor → classifier → sensor model → map → planner → robot.
"""

from ._base import BuildContext, Component, RunOutcome
from ._records import (
    ChannelInfo,
    ClassProbabilities,
    ExploratoryMovement,
    LocatedMeasurement,
    MapEstimate,
    MovementResult,
    Observations,
    Region,
    RobotState,
    SampleBatch,
    concatenate_batches,
)
from .classifier import Classifier
from .feature_extractor import FeatureExtractor
from .map import Map
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
    "ExploratoryMovement",
    "FeatureExtractor",
    "LocatedMeasurement",
    "Map",
    "MapEstimate",
    "MovementResult",
    "Observations",
    "Planner",
    "Region",
    "Robot",
    "RobotState",
    "RunOutcome",
    "SampleBatch",
    "Sensor",
    "SensorModel",
    "concatenate_batches",
]
