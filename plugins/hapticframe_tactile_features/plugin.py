"""Registration of the BioTac feature extractors ``emd-features`` and ``sparse-coding``.

Import-light: only hapticframe and the pydantic config module load here; numpy/scipy
(``emd-features``) and scikit-learn (``sparse-coding``) load when a component is built,
and numba (optional: the compiled EMD and lasso kernels) when one first computes.
"""

from __future__ import annotations

from collections.abc import Iterator

from hapticframe import ChannelSpec, FeatureExtractorSpec, Knob, hookimpl

from ._config import EMDFeaturesConfig, SparseCodingConfig

# What the default configs need (all three modalities): the kit feeds exactly these.
_FEATURE_TENSORS: dict[str, tuple[int, ...]] = {
    "pac_imfs": (8, 22),
    "pdc_imfs": (5, 5),
    "electrodes_window": (19, 5),
}


@hookimpl
def hapticframe_feature_extractors() -> Iterator[FeatureExtractorSpec]:
    yield FeatureExtractorSpec(
        name="emd-features",
        summary="BioTac feature tensors: streaming EMD of pac (8×22) and pdc (5×5), "
        "electrode windows (19×5).",
        config=EMDFeaturesConfig,
        factory="hapticframe_tactile_features._emd_features:EMDFeatureExtractor",
        validator="hapticframe_tactile_features._checks:check_emd",
        requires=("scipy",),
        # numba is optional: without it the numpy EMD runs (same numbers, ~15x slower,
        # too slow for the 10 ms streaming budget).
        install_hint="pip install 'hapticframe[learn]' (numba for the compiled EMD kernel)",
        consumes={
            "pac": ChannelSpec((22,), "count"),
            "pdc": ChannelSpec((), "count"),
            "electrodes": ChannelSpec((None,), "count", example=(19,)),
        },
        produces={
            name: ChannelSpec((None, None), "count", "IMFs or window per frame")
            for name in _FEATURE_TENSORS
        },
        sample_rate_hz=100.0,
        # The defaults already use the smallest windows allowed (512 and 64 samples); a
        # short delay and a lower sifting cap keep the kit's ~2,000 frames quick.
        check_config={"delay_frames": 1, "max_sifts": 10},
        knobs=(
            Knob("max_sifts", "more sifts per IMF: IMFs closer to a converged EMD, sifting "
                 "time per frame", values=(2, 5, 10, 20, 50)),
            Knob("sd_threshold", "a looser sifting stop: fewer sifts, IMFs further from a "
                 "converged EMD (0: always max_sifts)",
                 values=(0.0, 0.001, 0.003, 0.01, 0.03, 0.1, 0.3)),
            Knob("residue_ratio", "a higher residue stop: fewer IMFs extracted (the rest zero "
                 "rows), less sifting per frame", values=(0.0, 0.05, 0.1, 0.2)),
            Knob("delay_frames", "more look-ahead: IMFs further from the window's end effects, "
                 "features delay_frames frames later", values=(1, 2, 3, 5)),
        ),
    )
    yield FeatureExtractorSpec(
        name="sparse-coding",
        summary="Sparse codes of the BioTac feature tensors (lasso at λ = 1.2/√m, "
        "dictionaries by MiniBatchDictionaryLearning).",
        config=SparseCodingConfig,
        factory="hapticframe_tactile_features._sparse_coding:SparseCodingExtractor",
        validator="hapticframe_tactile_features._checks:check_sparse",
        capabilities=frozenset({"trainable"}),
        requires=("sklearn",),
        install_hint="pip install 'hapticframe[learn]'",
        consumes={
            name: ChannelSpec((None, None), "count", example=shape)
            for name, shape in _FEATURE_TENSORS.items()
        },
        produces={
            f"{m}_code": ChannelSpec((None,), "1", "sparse code (size: the atoms)")
            for m in ("pac", "pdc", "electrodes")
        },
        sample_rate_hz=100.0,
        check_config={"pac_atoms": 40, "pdc_atoms": 20, "electrodes_atoms": 20},
        # The atoms change the code sizes a classifier reads (an sf-rnn or fusion-rnn takes
        # them from its coder when its <modality>_code_size is left null) and need
        # dictionaries trained for them: a point of a sweep trains its own.
        knobs=(
            Knob("pac_atoms", "a larger pac dictionary: richer codes, lasso and fit time "
                 "growing with the atoms", values=(50, 100, 200, 400)),
            Knob("pdc_atoms", "a larger pdc dictionary: richer codes, lasso and fit time "
                 "growing with the atoms", values=(25, 50, 100, 200)),
            Knob("electrodes_atoms", "a larger electrode dictionary: richer codes, lasso and "
                 "fit time growing with the atoms", values=(25, 50, 100, 200)),
            Knob("encode_max_iter", "a lower lasso iteration cap: bounded encode time per "
                 "frame, codes short of the 1e-8 tolerance", low=10, high=1000, scale="log",
                 points=5, integer=True),
        ),
    )
