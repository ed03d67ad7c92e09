"""Checks of the contact-state classifiers that ``validate`` runs (import-light: no torch).

A classifier that can read none of its channels streams all-zero input, and one that is
neither trained by the run (``run.train_from``) nor loaded (``model_dir``) streams untrained
weights: both run to the end with meaningless states, so ``validate`` refuses them.
"""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

from hapticframe import Finding, Size, ValidationContext

from ._config import MODALITIES, amplitude_channel, code_channel

__all__ = ["check"]

_BIOTAC = frozenset({"pac", "pdc", "tac", "tdc", "electrodes", "position_m", "contact"})
_FEATURES = {"pac": "pac_imfs", "pdc": "pdc_imfs", "electrodes": "electrodes_window"}


def _delivered(view: Any) -> frozenset[str] | None:
    """The channels a bundled producer delivers; None for a type not known here."""
    if view.type == "biotac":
        return _BIOTAC
    modalities = getattr(view.config, "modalities", MODALITIES)
    if view.type == "emd-features":
        return frozenset(_FEATURES[m] for m in modalities)
    if view.type == "sparse-coding":
        channels = {code_channel(m) for m in modalities}
        if view.config.amplitude == "channel":
            channels |= {amplitude_channel(m) for m in modalities}
        return frozenset(channels)
    return None


def _untrained(config: Any, context: ValidationContext) -> Iterator[Finding]:
    if config.model_dir is not None or context.extra.get("command") == "train":
        return
    if getattr(context.run, "train_from", None):
        return
    yield Finding(
        "the classifier would stream untrained weights: set model_dir to what `hapticframe "
        "train` saved, or run.train_from to fit it before the run",
        field="model_dir",
    )


def _reads(config: Any) -> dict[str, str]:
    """The channels a recurrent classifier reads, each with the config field behind it."""
    fields: dict[str, str] = {}
    for modality in config.modalities:
        fields[code_channel(modality)] = f"{modality}_code_size"
        if config.reads_amplitude(modality):
            fields[amplitude_channel(modality)] = "amplitude_inputs"
    return fields


#: Copies of every parameter while training (the weights, their gradients, Adam's two
#: moments), and of every unit's activation kept for the backward pass (the GRU's gates).
_PARAMETER_COPIES = 4
_ACTIVATION_COPIES = 6


def _gru(inputs: int, units: int, layers: int) -> int:
    """Parameters of a stack of single-layer GRUs (three gates, two biases each)."""
    return 3 * (inputs + units + 2) * units + (layers - 1) * 3 * (2 * units + 2) * units


def _sizes(config: Any) -> Iterator[Size]:
    """The network's parameters and a training batch's activations, in float64."""
    if hasattr(config, "inputs"):  # linear-svm: one weight per input column and fold
        columns = sum(int(n) for n in config.inputs.values())
        yield Size("inputs", f"{columns} input columns per frame in "
                   f"{config.calibration_folds} calibrated folds",
                   bytes=8.0 * columns * (config.calibration_folds + 1),
                   remedy="name the input channels with their real sizes")
        yield Size("max_iter", f"up to {config.max_iter} LinearSVC iterations",
                   iterations=float(config.max_iter), remedy="lower max_iter")
        return
    sizes = {m: sum(config.input_groups(m).values()) for m in config.modalities}
    total = sum(sizes.values())
    if hasattr(config, "gru_units"):
        field, units, layers = "gru_units", config.gru_units, config.gru_layers
        parameters = total * config.fusion_units + _gru(config.fusion_units, units, layers)
        width = layers * units + config.fusion_units
    else:
        field, units, layers = "branch_units", config.branch_units, config.branch_layers
        parameters = sum(_gru(n, units, layers) for n in sizes.values())
        parameters += len(sizes) * units * config.fusion_units
        width = len(sizes) * layers * units + config.fusion_units
    yield Size(field, f"{parameters:.3g} network parameters while training",
               bytes=8.0 * _PARAMETER_COPIES * parameters,
               remedy=f"fewer units or layers ({field})")
    activations = config.batch_size * config.window_frames * (total + _ACTIVATION_COPIES * width)
    for field in ("window_frames", "batch_size"):
        yield Size(field, f"activations of a training batch of {config.batch_size} windows of "
                   f"{config.window_frames} frames", bytes=8.0 * activations,
                   iterations=float(config.window_frames),
                   remedy="lower window_frames or batch_size")


def check(config: Any, context: ValidationContext) -> Iterator[Finding | Size]:
    """Yield what a classifier cannot read, or reads untrained (module docstring), and what
    its network holds."""
    yield from _sizes(config)
    yield from _untrained(config, context)
    delivered = {i: _delivered(v) for i, v in context.inputs.items()}
    if not delivered or any(c is None for c in delivered.values()):
        return  # an input of unknown type may deliver anything
    available = frozenset().union(*(c for c in delivered.values() if c))
    reads = dict.fromkeys(config.inputs, "inputs") if hasattr(config, "inputs") else _reads(config)
    if not set(reads) & available:
        yield Finding(
            f"the classifier reads {', '.join(reads)}, none of which its inputs deliver "
            f"({', '.join(f'{i} ({context.inputs[i].type})' for i in delivered)} give "
            f"{', '.join(sorted(available))}); it would classify all-zero input. Wire it to "
            "the channels it reads (sparse-coding for sf-rnn and fusion-rnn)",
            field="inputs" if hasattr(config, "inputs") else "",
        )
        return
    if hasattr(config, "inputs") or config.model_dir is not None:
        return  # a loaded network's saved architecture replaces the configured one
    missing: dict[str, list[str]] = {}
    for channel, field in reads.items():
        if channel not in available:
            missing.setdefault(field, []).append(channel)
    for field, channels in missing.items():
        yield Finding(
            f"{', '.join(channels)} delivered by none of the inputs: the network would read "
            "zeros there (sparse-coding emits amplitudes with amplitude: channel)",
            field=field,
        )
    for view in context.inputs.values():
        if view.type != "sparse-coding":
            continue
        for modality in set(config.modalities) & set(view.config.modalities):
            if getattr(config, f"{modality}_code_size") is None:
                continue  # taken from these atoms at build time
            atoms = getattr(view.config, f"{modality}_atoms")
            if atoms != config.code_size(modality):
                yield Finding(
                    f"{modality}_code_size is {config.code_size(modality)} but "
                    f"{view.id!r} codes {modality} with {atoms} atoms: remove "
                    f"{modality}_code_size (it then follows the atoms) or make them equal",
                    field=f"{modality}_code_size",
                )
