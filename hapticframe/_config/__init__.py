"""Experiment files: loading, the registry-built model, and validation."""

from ._checks import ComponentView, Finding, ValidationContext
from ._load import LoadedFile, load_file, load_text
from ._sizes import ITERATION_LIMIT, MEMORY_LIMIT_BYTES, Size
from ._model import SCHEMA_VERSION, ExperimentRoot, RunSettings, build_experiment_model
from ._validate import ComponentEntry, Experiment, validate_data, validate_file, validate_mapping

__all__ = [
    "SCHEMA_VERSION",
    "ComponentEntry",
    "ComponentView",
    "Experiment",
    "ExperimentRoot",
    "ITERATION_LIMIT",
    "MEMORY_LIMIT_BYTES",
    "Finding",
    "LoadedFile",
    "RunSettings",
    "Size",
    "ValidationContext",
    "build_experiment_model",
    "load_file",
    "load_text",
    "validate_data",
    "validate_file",
    "validate_mapping",
]
