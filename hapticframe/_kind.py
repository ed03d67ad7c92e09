"""The seven plugin kinds and the order in which data flows between them."""

from __future__ import annotations

from enum import Enum

__all__ = ["Kind"]


class Kind(str, Enum):
    """A plugin kind.

    The declaration order is the direction of data flow:
    sensor → feature extractor → classifier → sensor model → map → planner → robot.
    """

    SENSOR = "sensor"
    FEATURE_EXTRACTOR = "feature_extractor"
    CLASSIFIER = "classifier"
    SENSOR_MODEL = "sensor_model"
    MAP = "map"
    PLANNER = "planner"
    ROBOT = "robot"

    @property
    def section(self) -> str:
        """The experiment-file key that lists components of this kind (``"sensors"``...)."""
        return f"{self.value}s"

    @property
    def hook_name(self) -> str:
        """The registration hook that yields specs of this kind."""
        return f"hapticframe_{self.section}"

    @classmethod
    def from_section(cls, section: str) -> Kind:
        for kind in cls:
            if kind.section == section:
                return kind
        raise KeyError(section)

    def __str__(self) -> str:  # "sensor", not "Kind.SENSOR", in messages
        return self.value
