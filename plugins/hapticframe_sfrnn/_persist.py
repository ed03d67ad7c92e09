"""What the classifiers' saved models must be: metadata schemas and a checked weights reader.

A model directory is checked whole before anything is built from it: ``model.json``
against a strict schema (types as written, bounded sizes, no list where an object
belongs), its config against the component's config class, and every tensor's name, dtype,
shape and finiteness against the network that metadata describes (built on torch's
``meta`` device, which allocates nothing). Each failure is a ValueError naming the file.
"""

from __future__ import annotations

import json
import math
import pickle
import zipfile
from collections.abc import Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any, Literal

from pydantic import BaseModel, ConfigDict, Field, ValidationError

from hapticframe.artifacts import check_regular_file, schema_error

if TYPE_CHECKING:
    import torch

__all__ = [
    "MAX_PARAMETERS",
    "RecurrentLimits",
    "RecurrentModelFile",
    "SVMModelFile",
    "read_weights",
    "unsafe_message",
    "validate_config",
]

#: Most parameters a saved recurrent network may declare (80 MB of float32; the thesis's
#: SF-RNN has about 0.1 M).
MAX_PARAMETERS = 20_000_000
#: Widest linear-svm input a saved model may declare (values per frame).
MAX_SVM_WIDTH = 1_000_000
# Byte allowance for the zip directory and the pickled structure beside the tensor data.
_WEIGHTS_OVERHEAD = 1 << 20
_PICKLE_MAGIC = b"\x80"

Size = Annotated[int, Field(ge=1, le=100_000)]
Units = Annotated[int, Field(ge=1, le=4096)]
Layers = Annotated[int, Field(ge=1, le=16)]
Finite = Annotated[float, Field(allow_inf_nan=False, ge=-1e6, le=1e6)]


class _Strict(BaseModel):
    # Types as written (no "51" for 51, no true for 1); unknown fields are errors.
    model_config = ConfigDict(strict=True, extra="forbid", frozen=True)


class RecurrentLimits(BaseModel):
    """Bounds on the sizes a saved recurrent model's config may declare.

    Checked before any network is built, so ``gru_units: 200000`` is refused from the
    metadata rather than by running out of memory; the whole network is further bounded
    by :data:`MAX_PARAMETERS`.
    """

    model_config = ConfigDict(strict=True, extra="ignore", frozen=True)

    pac_code_size: Size | None = None
    pdc_code_size: Size | None = None
    electrodes_code_size: Size | None = None
    fusion_units: Units | None = None
    gru_units: Units | None = None
    gru_layers: Layers | None = None
    branch_units: Units | None = None
    branch_layers: Layers | None = None


class RecurrentModelFile(_Strict):
    """``model.json`` of ``sf-rnn`` / ``fusion-rnn`` (format version 1)."""

    format: Literal["hapticframe-recurrent-classifier"]
    format_version: Literal[1]
    architecture: Literal["sf-rnn", "fusion-rnn"]
    versions: dict[str, str | None]
    config: dict[str, Any]
    modalities: list[Literal["pac", "pdc", "electrodes"]] = Field(min_length=1, max_length=3)
    inputs: dict[str, Size] = Field(min_length=1, max_length=6)
    modality_inputs: dict[str, list[str]]
    classes: list[str]
    fitted: bool
    feature_settings: dict[str, dict[str, Any]]
    training_metrics: dict[str, Any]
    saved_at: str


class SVMModelFile(_Strict):
    """``model.json`` of ``linear-svm`` (format version 1)."""

    format: Literal["hapticframe-linear-svm"]
    format_version: Literal[1]
    versions: dict[str, str | None]
    config: dict[str, Any]
    inputs: dict[str, Annotated[int, Field(ge=1, le=MAX_SVM_WIDTH)]] = Field(min_length=1)
    classes: list[str]
    fitted: bool
    intercept: Finite
    platt_a: Finite
    platt_b: Finite
    training_metrics: dict[str, Any]


def validate_config(path: Path, config_type: type[BaseModel], values: Mapping[str, Any]) -> Any:
    """``values`` (a saved config) validated strictly by ``config_type``; ValueError naming
    ``path`` and the field (``config.<field>``) otherwise."""
    try:
        # JSON mode: a saved tuple is a JSON list, which strict JSON validation accepts.
        return config_type.model_validate_json(json.dumps(dict(values)), strict=True)
    except ValidationError as exc:
        raise schema_error(path, exc, prefix="config") from None


def unsafe_message(path: Path) -> str:
    """Why a weights file holding more than tensors is refused (never how to load it)."""
    return (
        f"{path} is not a hapticframe artifact: it holds Python objects beside tensors, "
        "which loading would execute, so it may be unsafe. It was not loaded; use a model "
        "directory written by `hapticframe train` (or save())"
    )


def _short(exc: BaseException) -> str:
    text = str(exc).strip().splitlines()
    first = text[0] if text else ""
    return f"{type(exc).__name__}: {first[:200]}" if first else type(exc).__name__


def read_weights(
    path: Path, expected: Mapping[str, tuple[tuple[int, ...], torch.dtype]]
) -> dict[str, torch.Tensor]:
    """The tensors of ``weights.pt``, each checked against ``expected`` (name → shape, dtype).

    The file must be a torch zip archive no larger than ``expected`` needs; it is read with
    ``weights_only=True`` (tensors only); every expected tensor must be present with its
    shape and dtype, no other may be, and all values must be finite.

    Raises
    ------
    ValueError
        Naming the file: missing, empty, too large, truncated or not a torch archive, a
        pickle that would run code, a missing, extra, mis-shaped or non-finite tensor.
    """
    import torch

    budget = sum(
        math.prod(shape) * torch.empty((), dtype=dtype).element_size()
        for shape, dtype in expected.values()
    ) + _WEIGHTS_OVERHEAD
    check_regular_file(path, budget)
    try:
        with zipfile.ZipFile(path) as archive:
            declared = sum(info.file_size for info in archive.infolist())
    except (zipfile.BadZipFile, OSError, ValueError, EOFError):
        with path.open("rb") as stream:
            head = stream.read(1)
        if head == _PICKLE_MAGIC:
            raise ValueError(unsafe_message(path)) from None
        raise ValueError(
            f"{path} is truncated or is not a torch weights archive (not written by "
            "`hapticframe train`); train the model again"
        ) from None
    if declared > budget:  # a compressed member could otherwise expand without bound
        raise ValueError(
            f"{path} declares {declared} bytes of content; the model needs at most {budget}"
        )
    try:
        state = torch.load(path, map_location="cpu", weights_only=True)
    except pickle.UnpicklingError as exc:
        if "weights only" in str(exc).lower():
            raise ValueError(unsafe_message(path)) from None
        raise ValueError(f"{path} is truncated or corrupt: {_short(exc)}") from None
    except Exception as exc:  # torch reports a damaged archive as any of several types
        raise ValueError(f"{path} is truncated or corrupt: {_short(exc)}") from None
    if not isinstance(state, Mapping) or not all(isinstance(k, str) for k in state):
        raise ValueError(f"{path} does not hold a mapping of tensor names to tensors")
    missing = [k for k in expected if k not in state]
    extra = [k for k in state if k not in expected]
    if missing or extra:
        parts = []
        if missing:
            parts.append(f"lacks {', '.join(missing[:5])}")
        if extra:
            parts.append(f"has unexpected {', '.join(k[:80] for k in extra[:5])}")
        raise ValueError(
            f"{path} does not match the network model.json describes: {'; '.join(parts)}"
        )
    out: dict[str, torch.Tensor] = {}
    for name, (shape, dtype) in expected.items():
        tensor = state[name]
        if not isinstance(tensor, torch.Tensor) or tensor.layout != torch.strided:
            raise ValueError(f"{path}: {name} is not a dense tensor")
        if tuple(tensor.shape) != tuple(shape):
            raise ValueError(
                f"{path}: {name} has shape {tuple(tensor.shape)}, but model.json describes "
                f"{tuple(shape)}"
            )
        if tensor.dtype != dtype:
            raise ValueError(f"{path}: {name} holds {tensor.dtype}, expected {dtype}")
        bad = int((~torch.isfinite(tensor)).sum())
        if bad:
            raise ValueError(f"{path}: {name} holds {bad} NaN or infinite value(s)")
        out[name] = tensor
    return out
