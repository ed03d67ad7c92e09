"""Configuration of the contact-state classifiers (import-light: pydantic only).

The recurrent classifiers (``sf-rnn``, ``fusion-rnn``) read one sparse code per BioTac
modality, ``pac_code`` (200,), ``pdc_code`` (100,) and ``electrodes_code`` (100,), at the
100 Hz frame rate of the ``sparse-coding`` feature extractor. ``linear-svm`` reads any
configured channels flattened per frame.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Literal, TypeVar

from pydantic import Field, field_validator

from hapticframe import PluginConfig
from hapticframe.threads import ThreadCount

__all__ = [
    "AMPLITUDE_SIZE",
    "CLASSES",
    "DEFAULT_CODE_SIZES",
    "MODALITIES",
    "FusionRNNConfig",
    "LinearSVMConfig",
    "Modality",
    "RecurrentConfig",
    "SFRNNConfig",
    "amplitude_channel",
    "code_channel",
]

Modality = Literal["pac", "pdc", "electrodes"]
#: The BioTac modalities in the thesis's order (vibration, fluid pressure, electrodes).
MODALITIES: tuple[Modality, ...] = ("pac", "pdc", "electrodes")
#: Dictionary sizes of the thesis (Appendix A.2): 200, 100 and 100 atoms.
DEFAULT_CODE_SIZES: dict[str, int] = {"pac": 200, "pdc": 100, "electrodes": 100}
#: Contact states; ``classes[0]`` is the background state.
CLASSES: tuple[str, str] = ("free", "contact")
#: Values per frame of a ``<modality>_amplitude`` channel of ``sparse-coding``.
AMPLITUDE_SIZE = 2


def code_channel(modality: str) -> str:
    """The ``sparse-coding`` output channel of a modality (``pac`` → ``pac_code``)."""
    return f"{modality}_code"


def amplitude_channel(modality: str) -> str:
    """The ``sparse-coding`` amplitude channel of a modality (``pac`` → ``pac_amplitude``)."""
    return f"{modality}_amplitude"


_R = TypeVar("_R", bound="RecurrentConfig")


class RecurrentConfig(PluginConfig):
    """Settings shared by the recurrent classifiers: inputs, training and artifacts."""

    modalities: tuple[Modality, ...] = Field(
        MODALITIES,
        description="Modalities the network is built for; their code channels "
        "(<modality>_code) are read. A configured modality missing at run time is zero-filled.",
    )
    pac_code_size: int | None = Field(
        None, ge=1, le=10_000,
        description="Length of pac_code; None: the pac atoms of the sparse-coding input, "
        "taken at build time (thesis: 200 atoms), so that a sweep of its pac_atoms needs no "
        "matching change here.",
    )
    pdc_code_size: int | None = Field(
        None, ge=1, le=10_000,
        description="Length of pdc_code; None: the pdc atoms of the sparse-coding input "
        "(thesis: 100 atoms).",
    )
    electrodes_code_size: int | None = Field(
        None, ge=1, le=10_000,
        description="Length of electrodes_code; None: the electrode atoms of the "
        "sparse-coding input (thesis: 100 atoms).",
    )
    amplitude_inputs: bool = Field(
        False,
        description="Also read each modality's <modality>_amplitude (2 values per frame, "
        "from sparse-coding with amplitude='channel'): the tensor size that the coder's "
        "unit-norm scaling removes. Not in the thesis, which feeds the codes alone. A "
        "modality's code and amplitude are one input: when either is missing or invalid in "
        "a frame, both are zero-filled (Table A.1).",
    )
    amplitude_modalities: tuple[Modality, ...] | None = Field(
        None,
        description="With amplitude_inputs, the modalities whose amplitude is read (None: "
        "all configured ones). After the tare, the pdc and electrode amplitudes "
        "measure deformation relative to the fingertip at rest; the pac amplitude is the "
        "vibration power, which a tare cannot zero and which scales with the medium and "
        "the speed (impact power ~ density x speed^3), so a model fitted in one medium at one "
        "speed reads a quieter medium or a slower rake as its contact frames' slightly "
        "lower vibration. The perception bench reads pdc and electrodes only.",
    )
    amplitude_gain: float = Field(
        30.0,
        gt=0,
        le=1e4, description="Weight of the amplitude inputs after RMS scaling (codes have 1): two "
        "numbers beside 100-200 code atoms are otherwise drowned in the fusion layer's "
        "pre-activation. On the quick perception data (SF-RNN, 2 seeds) 30 gave the best "
        "robustness mean of 10, 30 and 100 (95.4 % against 94.2 % and 93.4 %).",
    )
    frame_rate_hz: float = Field(100.0, gt=0, le=100_000, description="Rate of the code frames.")
    dropout: float = Field(
        0.4, ge=0.0, lt=1.0, description="Dropout rate in training (thesis: 0.4)."
    )
    window_frames: int = Field(
        50, ge=2, le=100_000,
        description="Training window in frames (thesis: 500 ms at 100 Hz = 50)."
    )
    free_stride_frames: int = Field(
        10, ge=1, le=100_000,
        description="Sliding-window step over trials without contact (thesis: 10)."
    )
    contact_stride_frames: int = Field(
        5, ge=1, le=100_000, description="Sliding-window step over trials with contact (thesis: 5)."
    )
    learning_rate: float = Field(1e-3, gt=0, le=10.0, description="Adam learning rate.")
    weight_decay: float = Field(
        1e-4, ge=0, le=1.0, description="L2 penalty on the weights (Adam weight_decay)."
    )
    batch_size: int = Field(32, ge=1, le=100_000, description="Training windows per Adam step.")
    max_epochs: int = Field(40, ge=1, le=100_000, description="Upper bound on training epochs.")
    patience: int = Field(
        5, ge=1, le=100_000,
        description="Epochs without a better validation score before training stops."
    )
    early_stopping: Literal["balanced_accuracy", "loss"] = Field(
        "balanced_accuracy",
        description="Validation score that picks the best epoch and drives patience: frame "
        "balanced accuracy (ties broken by the loss), or the cross-entropy alone. The loss "
        "keeps rising once a few frames at contact onset and release are confidently wrong, "
        "while the accuracy is still improving, so stopping on it ends training at epoch 1-2.",
    )
    validation_fraction: float = Field(
        0.2,
        ge=0.0,
        lt=1.0,
        description="Share of the training trials held out (whole trials) for early stopping "
        "(thesis: 60/20/20 split; 0 trains without early stopping).",
    )
    balance_classes: bool = Field(
        True,
        description="Weight the cross-entropy by inverse class frequency over the training "
        "windows, on top of the thesis's oversampling.",
    )
    modality_dropout: float = Field(
        0.0,
        ge=0.0,
        lt=1.0,
        description="Probability of zeroing one modality for a whole training window, to "
        "prepare the network for missing modalities (0 = off, as the thesis).",
    )
    progress: bool = Field(
        True, description="Show a progress bar while training (tqdm, else one line per epoch); "
        "`hapticframe run --quiet` turns it off.",
    )
    threads: ThreadCount = Field(
        1,
        description="torch intra-op threads while training (restored afterwards): these small "
        "GRUs train fastest on one, and several threads on shared cores slow them ~10×.",
    )
    train_device: str = Field(
        "cpu",
        pattern=r"^(cpu|cuda(:[0-9]+)?)$",
        description="torch device that training runs on: cpu, or cuda / cuda:N for a GPU. "
        "The dropout masks and window order come from the same CPU generator either way; "
        "the trained network is moved back to the CPU, where it streams and is saved.",
    )
    model_dir: str | None = Field(
        None,
        description="Directory written by save() (weights.pt + model.json) to load at build "
        "time; the saved architecture replaces the one configured here.",
    )

    @field_validator("modalities")
    @classmethod
    def _canonical_modalities(cls, value: tuple[Modality, ...]) -> tuple[Modality, ...]:
        if not value:
            raise ValueError("name at least one modality")
        if len(set(value)) != len(value):
            raise ValueError(f"modalities repeat: {list(value)}")
        return tuple(m for m in MODALITIES if m in value)

    def code_size(self, modality: str) -> int:
        """Length of the code vector of ``modality`` (the thesis's when the field is None and
        no input has resolved it: see :meth:`with_code_sizes`)."""
        size = getattr(self, f"{modality}_code_size")
        return DEFAULT_CODE_SIZES[modality] if size is None else int(size)

    def with_code_sizes(self: _R, sizes: Mapping[str, int]) -> _R:
        """This config with each code size left None set from ``sizes`` (modality → atoms
        its input codes with); sizes set in the file are kept."""
        update = {f"{m}_code_size": int(n) for m, n in sizes.items()
                  if m in MODALITIES and getattr(self, f"{m}_code_size") is None}
        return self.model_copy(update=update) if update else self

    @field_validator("amplitude_modalities")
    @classmethod
    def _canonical_amplitude_modalities(
        cls, value: tuple[Modality, ...] | None
    ) -> tuple[Modality, ...] | None:
        if value is None:
            return None
        if len(set(value)) != len(value):
            raise ValueError(f"amplitude_modalities repeat: {list(value)}")
        return tuple(m for m in MODALITIES if m in value)

    def reads_amplitude(self, modality: str) -> bool:
        """Whether ``<modality>_amplitude`` is one of the inputs."""
        return self.amplitude_inputs and (
            self.amplitude_modalities is None or modality in self.amplitude_modalities
        )

    def input_groups(self, modality: str) -> dict[str, int]:
        """Channels read for ``modality`` and their sizes, in column order."""
        groups = {code_channel(modality): self.code_size(modality)}
        if self.reads_amplitude(modality):
            groups[amplitude_channel(modality)] = AMPLITUDE_SIZE
        return groups


class SFRNNConfig(RecurrentConfig):
    """SF-RNN (dissertation Fig. 2.2e): codes → fusion layer → GRU stack → two states."""

    fusion_units: int = Field(
        100, ge=1, le=10_000,
        description="Width of the fully connected fusion layer over all codes."
    )
    gru_layers: int = Field(4, ge=1, le=64, description="Stacked GRU layers (thesis: 4).")
    gru_units: int = Field(50, ge=1, le=4096, description="Units per GRU layer (thesis: 50).")


class FusionRNNConfig(RecurrentConfig):
    """Fusion RNN (Jain et al.): one GRU stack per modality, joined by a fully connected layer."""

    branch_layers: int = Field(2, ge=1, le=64, description="GRU layers per modality.")
    branch_units: int = Field(
        50, ge=1, le=4096,
        description="Units per GRU layer of each modality.",
    )
    fusion_units: int = Field(
        50, ge=1, le=10_000,
        description="Width of the fully connected layer joining the modalities."
    )


class LinearSVMConfig(PluginConfig):
    """Linear SVM with Platt-calibrated probabilities on channels flattened per frame."""

    inputs: dict[str, int] = Field(
        {"pac_code": 200, "pdc_code": 100, "electrodes_code": 100},
        description="Input channels and their flattened per-frame sizes, e.g. sparse codes "
        "(stage d), EMD tensors {'pac_imfs': 176, ...} (stage c) or raw frames "
        "{'pac': 22, 'pdc': 1, 'electrodes': 19}. Missing or invalid ones are zero-filled.",
    )
    c: float = Field(1.0, gt=0, le=1e6, description="LinearSVC regularisation C.")
    max_iter: int = Field(5000, ge=1, le=10_000_000, description="LinearSVC iteration cap.")
    calibration_folds: int = Field(
        3, ge=2, le=100, description="Folds (grouped by trial) for the Platt-scaling calibration."
    )
    balance_classes: bool = Field(
        True,
        description="class_weight='balanced' (stands in for the thesis's random oversampling "
        "of the contact class).",
    )
    frame_rate_hz: float = Field(100.0, gt=0, le=100_000, description="Rate of the input frames.")
    model_dir: str | None = Field(
        None,
        description="Directory written by save() (model.npz + model.json) to load at build "
        "time.",
    )

    @field_validator("inputs")
    @classmethod
    def _sizes(cls, value: dict[str, int]) -> dict[str, int]:
        if not value:
            raise ValueError("name at least one input channel")
        bad = {k: v for k, v in value.items() if int(v) < 1}
        if bad:
            raise ValueError(f"input sizes must be ≥ 1, got {bad}")
        return value
