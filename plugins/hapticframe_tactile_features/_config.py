"""Configuration of the BioTac feature extractors (import-light: pydantic only)."""

from __future__ import annotations

from typing import Literal

from pydantic import Field, field_validator, model_validator

from hapticframe import PluginConfig

__all__ = [
    "ELECTRODE_FRAMES",
    "MODALITIES",
    "PDC_FRAMES",
    "EMDFeaturesConfig",
    "Modality",
    "SparseCodingConfig",
    "feature_channel",
    "input_channel",
]

Modality = Literal["pac", "pdc", "electrodes"]
#: The three BioTac modalities, in the thesis's order.
MODALITIES: tuple[Modality, ...] = ("pac", "pdc", "electrodes")
#: Frames of pdc IMFs and of electrode values in one feature tensor (thesis: 5 × 10 ms).
PDC_FRAMES = 5
ELECTRODE_FRAMES = 5

_INPUT_CHANNEL = {"pac": "pac", "pdc": "pdc", "electrodes": "electrodes"}
_FEATURE_CHANNEL = {"pac": "pac_imfs", "pdc": "pdc_imfs", "electrodes": "electrodes_window"}


def input_channel(modality: Modality) -> str:
    """The BioTac sensor channel a modality reads."""
    return _INPUT_CHANNEL[modality]


def feature_channel(modality: Modality) -> str:
    """The ``emd-features`` output channel of a modality (the input of ``sparse-coding``)."""
    return _FEATURE_CHANNEL[modality]


def _unique_modalities(value: tuple[Modality, ...]) -> tuple[Modality, ...]:
    if not value:
        raise ValueError("name at least one modality")
    if len(set(value)) != len(value):
        raise ValueError(f"modalities repeat: {list(value)}")
    return tuple(m for m in MODALITIES if m in value)  # canonical order


class EMDFeaturesConfig(PluginConfig):
    """Streaming EMD feature tensors of the BioTac (dissertation Figure 2.2b-c)."""

    modalities: tuple[Modality, ...] = Field(
        MODALITIES,
        description="Modalities to compute; only their sensor channels are read "
        "(pac → pac_imfs, pdc → pdc_imfs, electrodes → electrodes_window).",
    )
    frame_rate_hz: float = Field(
        100.0,
        gt=0,
        le=100_000,
        description="BioTac frame rate (one pdc/electrode sample and one pac chunk per frame).",
    )
    pac_samples_per_frame: int = Field(
        22, ge=1, le=10_000,
        description="pac samples delivered per frame (22 at 2,200 Hz and 100 frames/s)."
    )
    electrode_count: int = Field(
        19, ge=1, le=1000, description="Electrodes per frame (19; 24 on the BioTac SP)."
    )
    pac_imfs: int = Field(
        8, ge=1, le=12, description="IMF rows of pac_imfs (zero rows where fewer IMFs exist)."
    )
    pdc_imfs: int = Field(
        5, ge=1, le=12, description="IMF rows of pdc_imfs (zero rows where fewer IMFs exist)."
    )
    pac_window_samples: int = Field(
        512,
        ge=512,
        le=1_048_576,
        description="pac ring buffer decomposed every frame, in samples (≥ 2^(8+1) for 8 IMFs).",
    )
    pdc_window_samples: int = Field(
        64,
        ge=64,
        le=1_048_576,
        description="pdc ring buffer decomposed every frame, in samples (≥ 2^(5+1) for 5 IMFs).",
    )
    delay_frames: int = Field(
        3,
        ge=0,
        le=50,
        description="Look-ahead in frames: the features emitted after frame k describe frame "
        "k - delay_frames, which then lies that far from the window's end, away from the EMD "
        "end effects. delay_s = delay_frames / frame_rate_hz.",
    )
    sd_threshold: float = Field(
        0.01,
        ge=0,
        le=1.0,
        description="Sifting stop: mean-envelope energy below this fraction of the proto-IMF "
        "energy (0 = fixed sifting). 0.01 (was 0.1): about 4 sifts per IMF instead of 2-3, "
        "pdc IMFs as orthogonal as a converged EMD's, +0.1 ms per frame "
        "(`hapticframe bench emd-fidelity`, docs/benchmarks.md).",
    )
    max_sifts: int = Field(50, ge=1, le=10_000, description="Cap on sifting iterations per IMF.")
    residue_ratio: float = Field(
        0.1,
        ge=0,
        le=1.0, description="Stop decomposing when ||residue|| < residue_ratio · ||last IMF|| "
        "(thesis: 10 %; 0 = off).",
    )
    mirrored_extrema: int = Field(
        2, ge=1, le=100, description="Extrema mirrored beyond each end of the window."
    )
    emd_backend: Literal["auto", "numba", "numpy"] = Field(
        "auto",
        description="EMD implementation: 'numba' (compiled sifting loop, ~15x faster, needs "
        "numba), 'numpy' (the reference), 'auto' (numba when installed). Same decomposition "
        "to rounding.",
    )

    _check_modalities = field_validator("modalities")(_unique_modalities)

    @model_validator(mode="after")
    def _windows_hold_delay(self) -> EMDFeaturesConfig:
        need_pac = self.pac_samples_per_frame * (self.delay_frames + 1)
        if self.pac_window_samples < need_pac:
            raise ValueError(f"pac_window_samples must be ≥ {need_pac} (one frame plus the delay)")
        need_pdc = PDC_FRAMES + self.delay_frames
        if self.pdc_window_samples < need_pdc:
            raise ValueError(f"pdc_window_samples must be ≥ {need_pdc} (5 frames plus the delay)")
        return self


class SparseCodingConfig(PluginConfig):
    """Sparse codes of the feature tensors by online dictionary learning (Figure 2.2d)."""

    modalities: tuple[Modality, ...] = Field(
        MODALITIES,
        description="Modalities to encode (pac → pac_code, pdc → pdc_code, "
        "electrodes → electrodes_code).",
    )
    pac_atoms: int = Field(
        200, ge=1, le=10_000,
        description="Dictionary size k for pac (thesis: 200).",
    )
    pdc_atoms: int = Field(
        100, ge=1, le=10_000,
        description="Dictionary size k for pdc (thesis: 100).",
    )
    electrodes_atoms: int = Field(
        100, ge=1, le=10_000, description="Dictionary size k for the electrodes (thesis: 100)."
    )
    pac_shape: tuple[int, int] = Field(
        (8, 22), description="Shape of one pac_imfs tensor (IMFs, samples)."
    )
    pdc_shape: tuple[int, int] = Field(
        (5, 5), description="Shape of one pdc_imfs tensor (IMFs, samples)."
    )
    electrodes_shape: tuple[int, int] = Field(
        (19, 5), description="Shape of one electrodes_window tensor (electrodes, frames)."
    )
    frame_rate_hz: float = Field(
        100.0, gt=0, le=100_000, description="Rate of the feature tensors (and of the codes)."
    )
    lambda_scale: float = Field(
        1.2,
        gt=0,
        le=1e3, description="Sparsity penalty λ = lambda_scale / sqrt(m), m the tensor size "
        "(Mairal et al. 2010: 1.2).",
    )
    encode_max_iter: int = Field(
        1000, ge=1, le=1_000_000,
        description="Coordinate-descent iteration cap of the lasso encoder."
    )
    encoder: Literal["auto", "numba", "sklearn"] = Field(
        "auto",
        description="Lasso encoder: 'numba' (our coordinate descent on the Gram matrix, "
        "~30x faster per call, needs numba), 'sklearn' (sparse_encode with lasso_cd, the "
        "reference), 'auto' (numba when installed). Same objective and tolerance (1e-8).",
    )
    fit_epochs: int = Field(
        10,
        ge=1,
        le=100_000, description="MiniBatchDictionaryLearning max_iter (passes over the data; early "
        "stopping may end sooner).",
    )
    fit_batch_size: int = Field(
        256, ge=1, le=1_000_000,
        description="MiniBatchDictionaryLearning batch_size.",
    )
    amplitude: Literal["drop", "channel"] = Field(
        "drop",
        description="What happens to the size that the centring and unit-norm scaling remove "
        "before the lasso: 'drop' (the thesis: codes only) or 'channel' (also emit "
        "<modality>_amplitude, shape (2,): log1p(norm / ref) - log 2 and asinh(mean / ref), "
        "norm and mean of the flattened tensor, ref the median training norm learned by "
        "fit). A deviation from the thesis: after the BioTac tare the size of the electrode "
        "tensor is the plainest sign of contact (≈ 4× larger in contact on the synthetic "
        "data), and unit-norm codes cannot carry it.",
    )
    dictionary_file: str | None = Field(
        None,
        description="Dictionaries saved by SparseCodingExtractor.save to load at build time: "
        "the .npz/.json pair's path without suffix, or the directory `hapticframe train` "
        "wrote for this component.",
    )

    _check_modalities = field_validator("modalities")(_unique_modalities)

    @field_validator("pac_shape", "pdc_shape", "electrodes_shape")
    @classmethod
    def _positive_shape(cls, value: tuple[int, int]) -> tuple[int, int]:
        if min(value) < 1:
            raise ValueError(f"tensor shape entries must be ≥ 1, got {value}")
        return value
