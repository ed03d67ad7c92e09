"""Registration of the contact-state classifiers ``sf-rnn``, ``fusion-rnn`` and ``linear-svm``.

Import-light: only hapticframe and the pydantic config module load here; torch loads when
a recurrent classifier is built, scikit-learn when ``linear-svm`` is fitted.
"""

from __future__ import annotations

from collections.abc import Iterator

from hapticframe import ClassifierSpec, hookimpl

from ._config import DEFAULT_CODE_SIZES, FusionRNNConfig, LinearSVMConfig, SFRNNConfig

#: What the default configs read: the three sparse codes of ``sparse-coding``.
_CODES: dict[str, tuple[int, ...]] = {f"{m}_code": (n,) for m, n in DEFAULT_CODE_SIZES.items()}
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
    )

