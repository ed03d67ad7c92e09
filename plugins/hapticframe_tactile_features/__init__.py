"""BioTac feature extractors: streaming EMD feature tensors and sparse codes (thesis ch. 2).

Registers ``emd-features`` and ``sparse-coding``. Importing this package is cheap; the
numerics load on first attribute access. The chain's latency is measured by
``hapticframe_bench`` (:func:`emd_backend_in_use` and :func:`encoder_in_use` say which
implementation a setting runs).
"""

from __future__ import annotations

from hapticframe import lazy_exports

from ._config import MODALITIES, EMDFeaturesConfig, SparseCodingConfig

__all__ = [
    "MODALITIES",
    "EMDFeatureExtractor",
    "EMDFeaturesConfig",
    "EMDResult",
    "FeatureStream",
    "RingBuffer",
    "SparseCodingConfig",
    "SparseCodingExtractor",
    "emd",
    "emd_backend_in_use",
    "encoder_in_use",
]

_LAZY = {
    "EMDResult": "._emd",
    "emd": "._emd",
    "FeatureStream": "._streaming",
    "RingBuffer": "._streaming",
    "EMDFeatureExtractor": "._emd_features",
    "SparseCodingExtractor": "._sparse_coding",
}


def emd_backend_in_use(backend: str = "auto") -> str:
    """The EMD implementation that ``emd_backend=backend`` runs here.

    Parameters
    ----------
    backend : {"auto", "numba", "numpy"}
        An ``EMDFeaturesConfig.emd_backend`` (or :func:`emd` ``backend``) setting.

    Returns
    -------
    str
        ``"numba"`` (the compiled sifting kernel) or ``"numpy"``.

    Raises
    ------
    ImportError
        For ``"numba"`` when numba is not installed.
    ValueError
        For an unknown name.
    """
    from ._emd import _use_kernel

    return "numba" if _use_kernel(backend) else "numpy"


def encoder_in_use(encoder: str = "auto") -> str:
    """The lasso encoder that ``SparseCodingConfig(encoder=encoder)`` runs here.

    Parameters
    ----------
    encoder : {"auto", "numba", "sklearn"}
        A ``SparseCodingConfig.encoder`` setting.

    Returns
    -------
    str
        ``"numba"`` (the compiled coordinate descent) or ``"sklearn"``.

    Raises
    ------
    ImportError
        For ``"numba"`` when numba is not installed.
    ValueError
        For an unknown name.
    """
    from ._sparse import _use_numba

    return "numba" if _use_numba(encoder) else "sklearn"

__getattr__, __dir__ = lazy_exports(__name__, _LAZY)
