"""The ``sf-rnn`` and ``fusion-rnn`` classifiers: sparse codes in, contact probabilities out.

One class layer serves both networks (:class:`RecurrentClassifier`); the subclasses only
say which network to build. Inputs are the configured modalities' code channels
(``pac_code``, ``pdc_code``, ``electrodes_code``) at 100 Hz.

Missing modalities (Table A.1)
------------------------------
A configured modality whose channel is absent from a batch, flagged invalid in
``SampleBatch.valid`` or non-finite in a frame is zero-filled in that frame: the zero code,
which is what ``sparse-coding`` itself emits for an invalid tensor, meaning "no activation".
Absent channels raise one :class:`UserWarning` per channel and component; every fill is
counted in :attr:`RecurrentClassifier.fill_report` and returned by :meth:`finalize`.
With ``amplitude_inputs`` a modality is its code and its ``<modality>_amplitude`` together:
a frame missing either has both zero-filled (and the network's modality groups, used by
``modality_dropout``, span both); ``amplitude_modalities`` narrows which modalities'
amplitudes are read (the others are their code alone).
Training with ``modality_dropout > 0`` prepares a network for such gaps.

Streaming and batch
-------------------
:meth:`update` runs the network one frame at a time and keeps the GRU hidden state between
calls; :meth:`predict_proba` (inherited) resets the state and runs the same per-frame code
over the whole recording, so chunked streaming equals the batch path bit for bit. Output
timestamps are the input's: any look-ahead delay lies upstream in ``emd-features``.
The per-frame step is not torch's: :class:`~._step.StreamingStep` runs the trained
network's equations in float64 (compiled with numba when installed), ≈ 10× quicker than a
batch-1 torch call and equal to torch's float32 output to about 1e-7 (tested to 1e-6). Its
weights are copied from the torch network at the first frame after each :meth:`reset`
(so once per stream), :meth:`fit` and :meth:`load`. Probabilities are float64.

Artifacts
---------
:meth:`save` writes ``weights.pt`` (``torch.save`` of the state dict: tensors only) and
``model.json`` (format, versions, config, modalities, classes, feature settings, training
metrics). :meth:`load` reads them with ``torch.load(weights_only=True)``; nothing is
unpickled. Config ``model_dir`` loads a saved model at build time.

Before training (no ``model_dir``, no :meth:`fit`), weights are drawn from a
:class:`torch.Generator` seeded from ``context.rng``: deterministic for a seed, so the
component runs and can be checked, but its probabilities mean nothing.
"""

from __future__ import annotations

import json
import platform
import time
import warnings
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import torch
from numpy.typing import ArrayLike
from pydantic import ValidationError

from hapticframe import atomic_path, atomic_write
from hapticframe.artifacts import read_json_object, schema_error
from hapticframe.kinds import BuildContext, Classifier, ClassProbabilities, RunOutcome, SampleBatch

from ._config import (
    CLASSES,
    MODALITIES,
    FusionRNNConfig,
    RecurrentConfig,
    SFRNNConfig,
    amplitude_channel,
    code_channel,
)
from ._functional import (
    INPUT_CLIP,
    FillReport,
    assemble_inputs,
    check_labels,
    rms_scale,
    softmax_rows,
    version_of,
)
from ._networks import FusionRNNNet, RecurrentNet, SFRNNNet, init_parameters
from ._persist import (
    MAX_PARAMETERS,
    RecurrentLimits,
    RecurrentModelFile,
    read_weights,
    validate_config,
)
from ._step import StreamingStep
from ._training import train_network

__all__ = ["MODEL_FORMAT", "FusionRNNClassifier", "RecurrentClassifier", "SFRNNClassifier"]

#: ``format`` field of ``model.json``.
MODEL_FORMAT = "hapticframe-recurrent-classifier"
_FORMAT_VERSION = 1


class RecurrentClassifier(Classifier):
    """Streaming two-state classifier over per-modality sparse codes (base of both RNNs)."""

    architecture: str = ""

    def __init__(self, config: RecurrentConfig, context: BuildContext) -> None:
        super().__init__(config, context)
        self._init_seed = int(context.rng.integers(2**62))
        self._fit_seed = int(context.rng.integers(2**62))
        self.fitted = False
        self.training_metrics: dict[str, Any] = {}
        self.feature_settings: dict[str, Any] = self._input_settings(context)
        self.fill_report = FillReport()
        self._warned: set[str] = set()
        self._build(config.with_code_sizes(self._input_code_sizes(context)))
        if config.model_dir is not None:
            self.load(config.model_dir)
        # One step on zeros now, so that loading (or compiling) the numba kernel happens at
        # build time, not in a live run's first frame.
        step = StreamingStep(self.net)
        step.step(np.zeros(sum(self.groups.values())), step.initial_state(),
                  np.empty(len(CLASSES)))

    # -- construction ------------------------------------------------------------------

    def _make_network(
        self, config: Any, modality_sizes: list[int]
    ) -> RecurrentNet:  # pragma: no cover - abstract
        raise NotImplementedError

    def _build(self, config: RecurrentConfig) -> None:
        self.config = config
        # Channels in column order (assembly and RMS scaling are per channel) and, per
        # modality, its columns (the network's groups: one branch or dropout unit each).
        self.groups: dict[str, int] = {}
        self.modality_channels: dict[str, tuple[str, ...]] = {}
        for m in config.modalities:
            channels = config.input_groups(m)
            self.groups.update(channels)
            self.modality_channels[m] = tuple(channels)
        self.modality_sizes = [
            sum(self.groups[c] for c in self.modality_channels[m]) for m in config.modalities
        ]
        self.net = self._make_network(config, self.modality_sizes)
        init_parameters(self.net, torch.Generator().manual_seed(self._init_seed))
        self.net.eval()
        self._scale = np.ones(sum(self.groups.values()))
        self._state: list[np.ndarray] | None = None
        # Built from the network's weights on first use (see update).
        self._step: StreamingStep | None = None

    @staticmethod
    def _input_code_sizes(context: BuildContext) -> dict[str, int]:
        """The code length of each modality an input emits (``<modality>_code`` of shape
        ``(n,)``): what a code size left None in the config becomes."""
        sizes: dict[str, int] = {}
        for component in context.inputs.values():
            channels = getattr(component, "output_channels", None)
            if not isinstance(channels, Mapping):
                continue
            for m in MODALITIES:
                info = channels.get(code_channel(m))
                shape = getattr(info, "shape", None)
                if m not in sizes and isinstance(shape, tuple) and len(shape) == 1:
                    sizes[m] = int(shape[0])
        return sizes

    @staticmethod
    def _input_settings(context: BuildContext) -> dict[str, Any]:
        # Feature extractors feeding this classifier describe their settings (delay, sizes);
        # a model must carry them so that run-time features match training features.
        settings = {}
        for name, component in context.inputs.items():
            value = getattr(component, "settings", None)
            if isinstance(value, Mapping):
                settings[name] = dict(value)
        return settings

    @property
    def classes(self) -> tuple[str, ...]:
        return CLASSES

    @property
    def modalities(self) -> tuple[str, ...]:
        return tuple(self.config.modalities)

    # -- streaming ---------------------------------------------------------------------

    def reset(self) -> None:
        self._state = None
        # Weights may have been changed in place since (self.net is public): take them
        # afresh for the next stream; a copy costs ~0.1 ms, once per stream.
        self._step = None

    def _scaled(self, batch: SampleBatch) -> np.ndarray:
        for name in self.groups:
            if name not in batch.channels and name not in self._warned and len(batch):
                self._warned.add(name)
                warnings.warn(
                    f"{self.architecture} {self.id!r}: input channel {name!r} is absent; "
                    "that modality is zero-filled",
                    UserWarning,
                    stacklevel=3,
                )
        x = self._assemble(batch, self.fill_report)
        np.divide(x, self._scale, out=x)  # in place: x is this call's own array
        return np.clip(x, -INPUT_CLIP, INPUT_CLIP, out=x)

    def _assemble(self, batch: SampleBatch, report: FillReport | None = None) -> np.ndarray:
        """Unscaled inputs, one row per frame, whole modalities zero-filled where incomplete."""
        x, present = assemble_inputs(batch, self.groups, report)
        if all(len(c) == 1 for c in self.modality_channels.values()):
            return x
        # A modality is all its channels: a frame missing one has all zero-filled.
        names = list(self.groups)
        bounds = np.cumsum([0, *self.groups.values()])
        for channels in self.modality_channels.values():
            idx = [names.index(c) for c in channels]
            whole = present[:, idx].all(axis=1)
            for j in idx:
                x[~whole, bounds[j] : bounds[j + 1]] = 0.0
        return x

    def update(self, batch: SampleBatch) -> ClassProbabilities:
        x = self._scaled(batch)
        logits = np.empty((len(batch), len(CLASSES)))
        step = self._step
        if step is None:
            step = self._step = StreamingStep(self.net)
        if self._state is None:
            self._state = step.initial_state()
        for i in range(len(batch)):
            step.step(x[i], self._state, logits[i])
        return ClassProbabilities(batch.timestamps_s, softmax_rows(logits), CLASSES)

    def predict_sequence(self, batch: SampleBatch) -> ClassProbabilities:
        """Probabilities for a whole recording in one network call, from a fresh state.

        The same computation as :meth:`predict_proba` (which steps frame by frame, as a
        stream does), run as one sequence through the GRUs: equal up to float32 rounding
        and far quicker for scoring many recordings. The streaming state is not touched.
        """
        x = torch.from_numpy(self._scaled(batch).astype(np.float32))
        with torch.no_grad():
            out, _ = self.net(x[None], self.net.initial_state(1))
        logits = out[0].numpy().astype(np.float64)
        return ClassProbabilities(batch.timestamps_s, softmax_rows(logits), CLASSES)

    # -- training ----------------------------------------------------------------------

    def fit(
        self,
        batches: Sequence[SampleBatch],
        labels: Sequence[ArrayLike],
        validation_batches: Sequence[SampleBatch] | None = None,
        validation_labels: Sequence[ArrayLike] | None = None,
    ) -> None:
        """Train on labelled trials: one batch and one label array (0 free, 1 contact) each.

        Training starts from the seeded initial weights every time, so the result depends
        only on the data and ``context.rng``'s seed, not on earlier calls. Channels missing
        from a training batch are zero-filled like at run time.

        ``validation_batches`` / ``validation_labels``, when given, are the early-stopping
        trials: every training trial is then trained on, the input scale is fitted on the
        training trials alone, and ``validation_fraction`` is not used. Without them
        ``validation_fraction`` of the training trials is held out at random.

        Raises
        ------
        ValueError
            On mismatched lengths, labels outside {0, 1}, or no frames.
        """
        if len(batches) != len(labels):
            raise ValueError(f"{len(batches)} batches but {len(labels)} label arrays")
        if (validation_batches is None) != (validation_labels is None):
            raise ValueError("give validation_batches and validation_labels together")
        xs, ys = [], []
        for batch, y in zip(batches, labels, strict=True):
            xs.append(self._assemble(batch))
            ys.append(check_labels(y, len(batch), len(CLASSES)))
        if not xs or sum(len(y) for y in ys) == 0:
            raise ValueError("fit needs at least one labelled frame")
        validation = None
        if validation_batches is not None and validation_labels is not None:
            if len(validation_batches) != len(validation_labels):
                raise ValueError(f"{len(validation_batches)} validation batches but "
                                 f"{len(validation_labels)} label arrays")
            val_xs, val_ys = [], []
            for batch, y in zip(validation_batches, validation_labels, strict=True):
                val_xs.append(self._assemble(batch))
                val_ys.append(check_labels(y, len(batch), len(CLASSES)))
            validation = (val_xs, val_ys)
        self._scale = rms_scale(np.vstack(xs), list(self.groups.values()))
        amplitudes = {amplitude_channel(m) for m in self.modalities}
        gain = np.concatenate([
            np.full(size, self.config.amplitude_gain if name in amplitudes else 1.0)
            for name, size in self.groups.items()
        ])  # fmt: skip
        self._scale = self._scale / gain
        with torch.no_grad():
            self.net.input_scale.copy_(torch.from_numpy(self._scale))
        scaled = [np.clip(x / self._scale, -INPUT_CLIP, INPUT_CLIP) for x in xs]
        if validation is not None:
            validation = ([np.clip(x / self._scale, -INPUT_CLIP, INPUT_CLIP)
                           for x in validation[0]], validation[1])
        init_parameters(self.net, torch.Generator().manual_seed(self._init_seed))
        # ``--quiet`` (context.progress False) overrides the component's own progress setting.
        config = (self.config if self.context.progress
                  else self.config.model_copy(update={"progress": False}))
        self.training_metrics = train_network(self.net, scaled, ys, config, self._fit_seed,
                                              validation)
        self.fitted = True
        self.reset()

    # -- artifacts ---------------------------------------------------------------------

    def metadata(self) -> dict[str, Any]:
        """What ``model.json`` holds."""
        return {
            "format": MODEL_FORMAT,
            "format_version": _FORMAT_VERSION,
            "architecture": self.architecture,
            "versions": {
                "hapticframe": version_of("hapticframe"),
                "torch": torch.__version__,
                "numpy": np.__version__,
                "python": platform.python_version(),
            },
            "config": self.config.model_dump(mode="json", exclude={"model_dir"}),
            "modalities": list(self.modalities),
            "inputs": dict(self.groups),
            "modality_inputs": {m: list(c) for m, c in self.modality_channels.items()},
            "classes": list(CLASSES),
            "fitted": self.fitted,
            "feature_settings": self.feature_settings,
            "training_metrics": self.training_metrics,
            "saved_at": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()),
        }

    def training_report(self) -> dict[str, Any]:
        """What the last fit did (:class:`hapticframe.kinds.Trainable`): a copy of
        :attr:`training_metrics`, also when they were read from a saved model; empty before."""
        return dict(self.training_metrics)

    def save(self, directory: str | Path) -> Path:
        """Write ``weights.pt`` and ``model.json`` into ``directory`` (created); return it."""
        out = Path(directory)
        out.mkdir(parents=True, exist_ok=True)
        with atomic_path(out / "weights.pt") as temp:
            torch.save(self.net.state_dict(), temp)
        atomic_write(out / "model.json", json.dumps(self.metadata(), indent=2, allow_nan=False))
        return out

    def load(self, directory: str | Path) -> None:
        """Adopt the model saved in ``directory`` (its architecture and weights).

        Everything is checked before anything is built: ``model.json`` against
        :class:`~._persist.RecurrentModelFile` and its config against this component's
        config class (strict types, bounded sizes, at most
        :data:`~._persist.MAX_PARAMETERS` parameters), then every tensor of ``weights.pt``
        against the network that config describes (names, shapes, dtypes, finite values,
        a positive input scale, non-zero linear weights).

        Raises
        ------
        ValueError
            Naming the file: missing, empty, truncated or corrupt files, another format or
            architecture, metadata that breaks the schema, tensors that do not fit it, or a
            weights file holding more than tensors (not loaded: it may be unsafe).
        """
        path = Path(directory)
        meta_path, weights_path = path / "model.json", path / "weights.pt"
        if not meta_path.exists() or not weights_path.exists():
            raise ValueError(f"{path} lacks model.json or weights.pt")
        meta = read_json_object(meta_path)
        if meta.get("format") != MODEL_FORMAT or meta.get("format_version") != _FORMAT_VERSION:
            raise ValueError(f"{meta_path} is not a {MODEL_FORMAT} v{_FORMAT_VERSION} file")
        if meta.get("architecture") != self.architecture:
            architecture = str(meta.get("architecture"))[:80]
            raise ValueError(f"{path} holds a {architecture!r} model, not {self.architecture!r}")
        try:
            record = RecurrentModelFile.model_validate(meta)
        except ValidationError as exc:
            raise schema_error(meta_path, exc) from None
        try:
            RecurrentLimits.model_validate(record.config)
        except ValidationError as exc:
            raise schema_error(meta_path, exc, prefix="config") from None
        saved = {**record.config, "model_dir": None, "progress": self.config.progress}
        config = validate_config(meta_path, type(self.config), saved)
        expected = self._expected_state(meta_path, record, config)
        state = read_weights(weights_path, expected)
        self._check_values(weights_path, state)
        self._build(config)
        self.net.load_state_dict(state)
        self.net.eval()
        self._scale = self.net.input_scale.numpy().astype(np.float64).copy()
        self.fitted = record.fitted
        self.training_metrics = dict(record.training_metrics)
        self.feature_settings = dict(record.feature_settings)

    def _expected_state(
        self, meta_path: Path, record: RecurrentModelFile, config: RecurrentConfig
    ) -> dict[str, tuple[tuple[int, ...], torch.dtype]]:
        """Names, shapes and dtypes of the tensors ``config``'s network holds, from a
        network on the ``meta`` device (no memory allocated), after checking that the rest
        of ``model.json`` agrees with ``config``."""
        groups: dict[str, int] = {}
        for m in config.modalities:
            groups.update(config.input_groups(m))
        if list(record.modalities) != list(config.modalities):
            raise ValueError(
                f"{meta_path}: modalities {record.modalities} differ from the config's "
                f"{list(config.modalities)}"
            )
        if record.inputs != groups:
            raise ValueError(
                f"{meta_path}: inputs {record.inputs} differ from what the config reads {groups}"
            )
        if list(record.classes) != list(CLASSES):
            raise ValueError(f"{meta_path}: classes {record.classes[:5]} are not {list(CLASSES)}")
        sizes = [sum(config.input_groups(m).values()) for m in config.modalities]
        with torch.device("meta"):
            shapes = self._make_network(config, sizes).state_dict()
        total = sum(t.numel() for t in shapes.values())
        if total > MAX_PARAMETERS:
            raise ValueError(
                f"{meta_path} describes a network of {total:.3g} parameters; the limit is "
                f"{MAX_PARAMETERS:.3g} (check gru_units, fusion_units and the code sizes)"
            )
        return {k: (tuple(t.shape), t.dtype) for k, t in shapes.items()}

    @staticmethod
    def _check_values(weights_path: Path, state: Mapping[str, torch.Tensor]) -> None:
        """Refuse weights that load but cannot classify: a scale that divides by zero, or a
        linear layer of zeros (every frame would get the same probabilities)."""
        scale = state["input_scale"]
        if bool((scale <= 0).any()):
            bad = int((scale <= 0).sum())
            raise ValueError(
                f"{weights_path}: input_scale holds {bad} zero or negative value(s); every "
                "input is divided by it"
            )
        for name, tensor in state.items():
            if name.endswith(".weight") and not bool(tensor.any()):
                raise ValueError(
                    f"{weights_path}: {name} is all zero, so every frame would get the same "
                    "probabilities"
                )

    def finalize(self, outcome: RunOutcome) -> Mapping[str, Any]:
        report = self.fill_report.as_dict()
        metrics: dict[str, Any] = {}
        for what, counts in report.items():
            for name, count in counts.items():
                metrics[f"{self.id}_{name}_{what}"] = count
        return metrics


class SFRNNClassifier(RecurrentClassifier):
    """SF-RNN (dissertation Fig. 2.2e): sparse codes → fusion → 4 × 50 GRU → free/contact."""

    architecture = "sf-rnn"

    def __init__(self, config: SFRNNConfig, context: BuildContext) -> None:
        super().__init__(config, context)

    def _make_network(self, config: SFRNNConfig, modality_sizes: list[int]) -> RecurrentNet:
        return SFRNNNet(
            modality_sizes,
            config.fusion_units,
            config.gru_layers,
            config.gru_units,
            config.dropout,
            len(CLASSES),
        )


class FusionRNNClassifier(RecurrentClassifier):
    """Fusion RNN baseline: one GRU stack per modality joined by a fully connected layer."""

    architecture = "fusion-rnn"

    def __init__(self, config: FusionRNNConfig, context: BuildContext) -> None:
        super().__init__(config, context)

    def _make_network(self, config: FusionRNNConfig, modality_sizes: list[int]) -> RecurrentNet:
        return FusionRNNNet(
            modality_sizes,
            config.branch_layers,
            config.branch_units,
            config.fusion_units,
            config.dropout,
            len(CLASSES),
        )
