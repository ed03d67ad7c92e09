"""Checks of the BioTac feature extractors that ``validate`` runs (import-light: no numpy).

``emd-features`` must read a BioTac's raw channels, ``sparse-coding`` the tensors of
``emd-features`` in the shapes it configures, and ``sparse-coding`` needs dictionaries: loaded
(``dictionary_file``) or fitted by the run (``run.train_from``).
"""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

from hapticframe import Finding, Size, ValidationContext

from ._config import ELECTRODE_FRAMES, PDC_FRAMES, feature_channel, input_channel

__all__ = ["check_emd", "check_sparse"]

#: What the bundled producers deliver, by type (others are not known before they are built).
_CHANNELS: dict[str, frozenset[str]] = {
    "biotac": frozenset({"pac", "pdc", "tac", "tdc", "electrodes", "position_m", "contact"}),
    "sandbox-force": frozenset({"force_n"}),
    "robotiq-ft300": frozenset({"force_n", "torque_nm"}),
    "force-observer": frozenset({"force_n"}),
    "bno055": frozenset({"acceleration_m_per_s2", "linear_acceleration_m_per_s2",
                         "gravity_m_per_s2", "angular_velocity_rad_per_s", "orientation_wxyz",
                         "calibration"}),
}
#: Most dictionary entries of one modality (atoms x tensor size, float64: 800 MB).
MAX_DICTIONARY = 100_000_000


#: Arrays of the window's length that one sift holds (the signal, its two envelopes, their
#: mean, the extrema and their mirrored copies).
_SIFT_ARRAYS = 6


def _emd_sizes(config: Any) -> Iterator[Size]:
    """One frame's decomposition: imfs x sifts passes over each window."""
    for modality, imfs, window in (
        ("pac", config.pac_imfs, config.pac_window_samples),
        ("pdc", config.pdc_imfs, config.pdc_window_samples),
    ):
        if modality not in config.modalities:
            continue
        # A streaming extractor must keep up with its input: the work of one second of it.
        work = float(imfs) * config.max_sifts * window * config.frame_rate_hz
        what = (f"{imfs} {modality} IMFs of up to {config.max_sifts} sifts over a "
                f"{window}-sample window, for each of {config.frame_rate_hz:g} frames a second "
                "(sample updates per second of input)")
        remedy = f"lower max_sifts or {modality}_window_samples"
        memory = 8.0 * _SIFT_ARRAYS * window * (imfs + 1)
        for field in ("max_sifts", f"{modality}_window_samples", f"{modality}_imfs"):
            yield Size(field, what, bytes=memory, iterations=work, remedy=remedy)


def check_emd(config: Any, context: ValidationContext) -> Iterator[Finding | Size]:
    """Refuse ``emd-features`` whose inputs are all known not to deliver its channels;
    declare what a frame's decomposition iterates over."""
    yield from _emd_sizes(config)
    known = {i: _CHANNELS.get(v.type) for i, v in context.inputs.items()}
    if not known or any(c is None for c in known.values()):
        return
    wanted = [input_channel(m) for m in config.modalities]
    if not any(ch in c for c in known.values() if c for ch in wanted):
        yield Finding(
            f"emd-features reads {', '.join(wanted)}, which none of its inputs delivers "
            f"({', '.join(f'{i} ({context.inputs[i].type})' for i in known)}); wire it to a "
            "BioTac",
            field="modalities",
        )


def _emd_shapes(view: Any) -> dict[str, tuple[int, int]]:
    c = view.config
    return {
        "pac": (c.pac_imfs, c.pac_samples_per_frame),
        "pdc": (c.pdc_imfs, PDC_FRAMES),
        "electrodes": (c.electrode_count, ELECTRODE_FRAMES),
    }


def check_sparse(config: Any, context: ValidationContext) -> Iterator[Finding | Size]:
    """Refuse untrained dictionaries, unreadable inputs and shapes its input does not emit."""
    if (config.dictionary_file is None and context.extra.get("command") != "train"
            and not getattr(context.run, "train_from", None)):
        yield Finding(
            "sparse-coding has no dictionaries: set dictionary_file to what `hapticframe train` "
            "saved, or run.train_from to fit them before the run",
            field="dictionary_file",
        )
    for modality in config.modalities:
        rows, cols = getattr(config, f"{modality}_shape")
        atoms = getattr(config, f"{modality}_atoms")
        entries = atoms * rows * cols
        # Coding sweeps over every atom until a frame converges: per second of input.
        sweeps = float(config.encode_max_iter) * atoms * config.frame_rate_hz
        coding = (f"the {modality} dictionary of {atoms} atoms of {rows} x {cols}, and up to "
                  f"{config.encode_max_iter} coding sweeps over its atoms for each of "
                  f"{config.frame_rate_hz:g} frames a second (atom updates per second of input)")
        for field in (f"{modality}_atoms", "encode_max_iter"):
            yield Size(field, coding, bytes=8.0 * entries, iterations=sweeps,
                       remedy=f"lower {modality}_atoms or encode_max_iter")
        # Fitting holds a batch of tensors, their codes and the dictionary's gradient.
        batch = float(config.fit_batch_size) * (rows * cols + atoms)
        yield Size("fit_batch_size", f"a fitting batch of {config.fit_batch_size} {modality} "
                   "tensors and their codes", bytes=8.0 * (batch + 2 * entries),
                   remedy="lower fit_batch_size")
    for modality in config.modalities:
        rows, cols = getattr(config, f"{modality}_shape")
        entries = getattr(config, f"{modality}_atoms") * rows * cols
        if entries > MAX_DICTIONARY:
            yield Finding(
                f"the {modality} dictionary would hold {entries:.3g} values "
                f"({8.0 * entries / 2**30:.3g} GiB); the limit is {MAX_DICTIONARY:.0e}",
                field=f"{modality}_shape",
            )
    for view in context.inputs.values():
        if view.type in _CHANNELS:
            yield Finding(
                f"sparse-coding encodes emd-features tensors; its input {view.id!r} "
                f"({view.type}) delivers raw channels: put emd-features between them",
            )
        elif view.type == "emd-features" and config.dictionary_file is None:
            shapes = _emd_shapes(view)
            for modality in set(config.modalities) & set(view.config.modalities):
                shape = tuple(getattr(config, f"{modality}_shape"))
                if shape != shapes[modality]:
                    yield Finding(
                        f"{modality}_shape is {shape} but {view.id!r} emits "
                        f"{feature_channel(modality)} of shape {shapes[modality]}",
                        field=f"{modality}_shape",
                    )
