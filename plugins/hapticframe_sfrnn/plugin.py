"""Registration of the contact-state classifiers ``sf-rnn``, ``fusion-rnn`` and ``linear-svm``.

Import-light: only hapticframe and the pydantic config module load here; torch loads when
a recurrent classifier is built, scikit-learn when ``linear-svm`` is fitted.
"""

from __future__ import annotations

from collections.abc import Iterator

from hapticframe import ChannelSpec, ClassifierSpec, Knob, hookimpl

from ._config import DEFAULT_CODE_SIZES, FusionRNNConfig, LinearSVMConfig, SFRNNConfig

#: What the default configs read: the three sparse codes of ``sparse-coding``.
#: Codes of any size (the coder's atoms); the kit feeds the default sizes.
_CODES: dict[str, ChannelSpec] = {
    f"{m}_code": ChannelSpec((None,), "1", "a sparse code of the modality", example=(n,))
    for m, n in DEFAULT_CODE_SIZES.items()
}
_LEARN_HINT = "pip install 'hapticframe[learn]'"
# Small networks keep the kit's few thousand single-frame steps quick; same code paths.
_CHECK_SFRNN = {"fusion_units": 16, "gru_layers": 2, "gru_units": 8, "progress": False}
_CHECK_FUSION = {"branch_layers": 1, "branch_units": 8, "fusion_units": 8, "progress": False}


@hookimpl
def hapticframe_classifiers() -> Iterator[ClassifierSpec]:
    yield ClassifierSpec(
        name="sf-rnn",
        summary="SF-RNN: sparse codes → fully connected fusion → 4 × 50 GRU → free / "
        "contact (dissertation Fig. 2.2e).",
        config=SFRNNConfig,
        factory="hapticframe_sfrnn._recurrent:SFRNNClassifier",
        validator="hapticframe_sfrnn._checks:check",
        capabilities=frozenset({"trainable"}),
        requires=("torch",),
        install_hint=_LEARN_HINT,
        consumes=dict(_CODES),
        sample_rate_hz=100.0,
        check_config=dict(_CHECK_SFRNN),
        knobs=(
            Knob("gru_units", "wider GRU layers: more capacity, step time growing as "
                 "units²", values=(16, 25, 50, 100)),
            Knob("gru_layers", "deeper GRU: more capacity, step time linear in layers",
                 values=(1, 2, 4)),
            Knob("fusion_units", "a wider fusion layer: more capacity, a larger first matrix "
                 "product per frame", values=(25, 50, 100, 200)),
            Knob("max_epochs", "more training epochs (early stopping may end sooner): a "
                 "better fit, training time", values=(10, 20, 40)),
        ),
    )
    yield ClassifierSpec(
        name="fusion-rnn",
        summary="Fusion RNN baseline: one GRU per modality joined by a fully connected layer.",
        config=FusionRNNConfig,
        factory="hapticframe_sfrnn._recurrent:FusionRNNClassifier",
        validator="hapticframe_sfrnn._checks:check",
        capabilities=frozenset({"trainable"}),
        requires=("torch",),
        install_hint=_LEARN_HINT,
        consumes=dict(_CODES),
        sample_rate_hz=100.0,
        check_config=dict(_CHECK_FUSION),
        knobs=(
            Knob("branch_units", "wider per-modality GRUs: more capacity, step time growing "
                 "as units²", values=(16, 25, 50, 100)),
            Knob("branch_layers", "deeper per-modality GRUs: more capacity, step time linear "
                 "in layers", values=(1, 2, 3)),
            Knob("fusion_units", "a wider joining layer: more capacity, more work per frame",
                 values=(25, 50, 100)),
        ),
    )
    yield ClassifierSpec(
        name="linear-svm",
        summary="Per-frame linear SVM with Platt-calibrated probabilities on any flattened "
        "channels (raw frames, EMD tensors or sparse codes).",
        config=LinearSVMConfig,
        factory="hapticframe_sfrnn._linear_svm:LinearSVMClassifier",
        validator="hapticframe_sfrnn._checks:check",
        capabilities=frozenset({"trainable"}),
        requires=("sklearn",),
        install_hint=_LEARN_HINT,
        consumes=dict(_CODES),
        sample_rate_hz=100.0,
        knobs=(
            Knob("max_iter", "a lower LinearSVC iteration cap: bounded training time, an "
                 "unconverged boundary", values=(200, 1000, 5000)),
            Knob("calibration_folds", "more Platt folds: steadier probabilities, one SVC fit "
                 "per fold", values=(2, 3, 5)),
        ),
    )

