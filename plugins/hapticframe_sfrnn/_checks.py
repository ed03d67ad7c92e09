"""Checks of the contact-state classifiers that ``validate`` runs (import-light: no torch).

A classifier that can read none of its channels streams all-zero input, and one that is
neither trained by the run (``run.train_from``) nor loaded (``model_dir``) streams untrained
weights: both run to the end with meaningless states, so ``validate`` refuses them.
"""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

from hapticframe import Finding, ValidationContext

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


def check(config: Any, context: ValidationContext) -> Iterator[Finding]:
    """Yield what a classifier cannot read, or reads untrained (module docstring)."""
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
