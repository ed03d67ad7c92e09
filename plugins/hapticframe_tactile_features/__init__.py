"""BioTac feature extractors: streaming EMD feature tensors and sparse codes (thesis ch. 2).

Registers ``emd-features`` and ``sparse-coding``. Importing this package is cheap; the
numerics load on first attribute access.
"""

from __future__ import annotations

import importlib
from typing import Any

from ._config import MODALITIES, EMDFeaturesConfig, SparseCodingConfig

__all__ = [
    "EMDFeatureExtractor",
    "EMDFeaturesConfig",
    "EMDResult",
    "FeatureStream",
    "MODALITIES",
    "RingBuffer",
    "SparseCodingConfig",
    "SparseCodingExtractor",
    "compare_emd_with_pyemd",
    "emd",
    "measure_chain_latency",
]

_LAZY = {
    "EMDResult": "._emd",
    "emd": "._emd",
    "FeatureStream": "._streaming",
    "RingBuffer": "._streaming",
    "EMDFeatureExtractor": "._emd_features",
    "SparseCodingExtractor": "._sparse_coding",
    "measure_chain_latency": "._latency",
    "compare_emd_with_pyemd": "._latency",
}


def __getattr__(name: str) -> Any:
    if name in _LAZY:
        return getattr(importlib.import_module(_LAZY[name], __name__), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))
