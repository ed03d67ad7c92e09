"""Experiment files: loading, the registry-built model, and validation."""

from hapticframe._config._checks import (
    ComponentView,
    Finding,
    ValidationContext,
    contract_mismatch,
)
from hapticframe._config._load import LoadedFile, load_file, load_text
from hapticframe._config._model import (
    SCHEMA_VERSION,
    ComponentEntry,
    Experiment,
    ExperimentRoot,
    RunSettings,
    build_experiment_model,
)
from hapticframe._config._sizes import ITERATION_LIMIT, MEMORY_LIMIT_BYTES, Size
from hapticframe._config._validate import (
    validate_data,
    validate_file,
    validate_mapping,
)

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
    "contract_mismatch",
    "load_file",
    "load_text",
    "validate_data",
    "validate_file",
    "validate_mapping",
]
