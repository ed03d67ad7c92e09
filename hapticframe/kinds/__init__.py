"""The behavioural interfaces of the seven plugin kinds and the records they exchange.

One module per kind states its contract; the data records are shared. Data flows one way:
sensor → feature extractor → classifier → sensor model → map → planner → robot.
What only some components can do (train, persist, evaluate on a grid) is declared in
:mod:`hapticframe.kinds.capabilities`. :mod:`hapticframe.kinds.world` is the interface of the
simulated worlds a simulated robot consults for the sand's force (not a kind of its own).
"""

from hapticframe.kinds._base import (
    OUTLINE_LEVEL,
    BuildContext,
    Component,
    InputAlignment,
    RunOutcome,
)
from hapticframe.kinds._clock import RunClock
from hapticframe.kinds._records import (
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
from hapticframe.kinds.capabilities import (
    Device,
    EnvironmentCoupled,
    GridQueryable,
    Persistent,
    PhysicalTruthSource,
    RobotFollower,
    Trainable,
)
from hapticframe.kinds.classifier import Classifier
from hapticframe.kinds.feature_extractor import FeatureExtractor
from hapticframe.kinds.map import Map, query_points
from hapticframe.kinds.planner import Planner
from hapticframe.kinds.robot import Robot
from hapticframe.kinds.sensor import Sensor
from hapticframe.kinds.sensor_model import CalibrationRecording, SensorModel, TrainableSensorModel
from hapticframe.kinds.world import PlateMovement, PlateSample, TruthState, World, WorldResponse

__all__ = [
    "BuildContext",
    "CalibrationRecording",
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
    "PlateMovement",
    "PlateSample",
    "Region",
    "Robot",
    "RobotFollower",
    "RobotState",
    "RunClock",
    "RunOutcome",
    "SampleBatch",
    "Sensor",
    "SensorModel",
    "Trainable",
    "TrainableSensorModel",
    "TruthState",
    "World",
    "WorldResponse",
    "concatenate_batches",
    "query_points",
]
