"""The ``sparse-coding`` feature extractor: feature tensors in, sparse codes out."""

from __future__ import annotations

import json
import math
import platform
from collections.abc import Mapping, Sequence
from importlib.metadata import PackageNotFoundError, version
from pathlib import Path
from typing import Annotated, Any, Literal

import numpy as np
from numpy.typing import NDArray
from pydantic import BaseModel, ConfigDict, Field, ValidationError, model_validator

from hapticframe import atomic_write, save_npz
from hapticframe.artifacts import npz_budget, read_json_object, read_npz_arrays, schema_error
from hapticframe.kinds import BuildContext, ChannelInfo, FeatureExtractor, SampleBatch

from ._config import Modality, SparseCodingConfig, feature_channel
from ._sparse import (
    AMPLITUDE_FEATURES,
    TensorEncoder,
    amplitude_features,
    amplitude_reference,
    learn_dictionary,
    normalise_rows,
    random_dictionary,
    sparsity_penalty,
)

__all__ = ["DICTIONARY_FORMAT", "SparseCodingExtractor"]

#: ``format`` field of the JSON metadata written by :meth:`SparseCodingExtractor.save`.
DICTIONARY_FORMAT = "hapticframe-sparse-dictionaries"
_FORMAT_VERSION = 2
#: Versions :meth:`SparseCodingExtractor.load` reads (1: no amplitude references).
_READABLE_VERSIONS = (1, 2)


def _version_of(distribution: str) -> str | None:
    try:
        return version(distribution)
    except PackageNotFoundError:
        return None


def _code_channel(modality: Modality) -> str:
    return f"{modality}_code"


def _amplitude_channel(modality: Modality) -> str:
    return f"{modality}_amplitude"


class SparseCodingExtractor(FeatureExtractor):
    """Sparse codes of the flattened feature tensors (dissertation Figure 2.2d).

    Each configured modality's tensor (``pac_imfs`` (8, 22), ``pdc_imfs`` (5, 5),
    ``electrodes_window`` (19, 5)) is flattened to m values, centred and scaled to unit
    ℓ2 norm, and encoded by the lasso ``min_u 0.5 ||z - D^T u||^2 + λ ||u||_1`` with
    λ = 1.2 / sqrt(m) over a dictionary D of k atoms (200, 100, 100), giving ``pac_code``,
    ``pdc_code`` and ``electrodes_code``.

    With config ``amplitude="channel"`` (not the thesis) each modality also gets
    ``<modality>_amplitude`` (2,): the size and offset the normalisation removed
    (:func:`._sparse.amplitude_features`), relative to the median centred norm of the
    training tensors (learned by :meth:`fit`, saved with the dictionaries; 1.0 before).

    Encoding (config ``encoder``) is our coordinate descent on the Gram matrix
    (:mod:`._lasso_kernel`, compiled with numba) or, without numba,
    :func:`sklearn.decomposition.sparse_encode` with ``algorithm="lasso_cd"`` and
    ``alpha=λ``: the same objective and stopping tolerance, ≈ 30× less time per frame.
    The transform of
    ``MiniBatchDictionaryLearning`` / ``SparseCoder`` defaults to OMP, which ignores α
    (it keeps m/10 non-zeros whatever λ is), so it is never used.

    Dictionaries
    ------------
    - Before :meth:`fit` (and without ``dictionary_file``) each modality has k random unit
      atoms with Gaussian entries drawn from ``context.rng``: deterministic for a seed, so
      the component runs and can be checked before training, but the codes carry no learned
      structure.
    - :meth:`fit` learns each dictionary with ``MiniBatchDictionaryLearning`` (α = λ, the
      random atoms as ``dict_init``, a seed drawn from ``context.rng``).
    - :meth:`save` / :meth:`load` write and read ``.npz`` arrays (``allow_pickle=False``)
      plus ``.json`` metadata with versions and settings; config ``dictionary_file`` loads
      one at build time.

    A tensor holding NaN or infinity, or flagged invalid in the input's ``valid``, gets the
    zero code and ``valid = False``; a constant tensor gets the zero code (it has no
    direction) and stays valid.
    """

    def __init__(self, config: SparseCodingConfig, context: BuildContext) -> None:
        super().__init__(config, context)
        self.modalities: tuple[Modality, ...] = tuple(config.modalities)
        self.dictionaries: dict[Modality, NDArray[np.float64]] = {
            m: random_dictionary(self.n_atoms(m), self.dimension(m), context.rng)
            for m in self.modalities
        }
        self.amplitude_references: dict[Modality, float] = {m: 1.0 for m in self.modalities}
        self._seed = int(context.rng.integers(2**31 - 1))
        self.fitted = False
        self.fit_stats: dict[str, Any] = {}
        self._refresh()
        if config.dictionary_file is not None:
            self.load(config.dictionary_file)

    # -- settings ----------------------------------------------------------------------

    def tensor_shape(self, modality: Modality) -> tuple[int, int]:
        """Shape of the input tensor of ``modality``."""
        shapes = {
            "pac": self.config.pac_shape,
            "pdc": self.config.pdc_shape,
            "electrodes": self.config.electrodes_shape,
        }
        return shapes[modality]

    def dimension(self, modality: Modality) -> int:
        """m: the length of the flattened tensor."""
        rows, cols = self.tensor_shape(modality)
        return rows * cols

    def n_atoms(self, modality: Modality) -> int:
        """k: the dictionary size of ``modality``."""
        return {
            "pac": self.config.pac_atoms,
            "pdc": self.config.pdc_atoms,
            "electrodes": self.config.electrodes_atoms,
        }[modality]

    def penalty(self, modality: Modality) -> float:
        """λ = lambda_scale / sqrt(m)."""
        return sparsity_penalty(self.dimension(modality), self.config.lambda_scale)

    def _refresh(self) -> None:
        # Contiguous copies and Gram matrices once per dictionary, not once per frame.
        self._dictionaries_c = {
            m: np.ascontiguousarray(d, dtype=np.float64) for m, d in self.dictionaries.items()
        }
        self._grams = {m: d @ d.T for m, d in self._dictionaries_c.items()}
        self._penalties = {m: self.penalty(m) for m in self.modalities}
        self._encoders = {
            m: TensorEncoder(self._dictionaries_c[m], self._penalties[m], gram=self._grams[m],
                             max_iter=self.config.encode_max_iter, backend=self.config.encoder)
            for m in self.modalities
        }
        # Per modality: input channel, expected tensor shape and flattened length, looked
        # up once rather than every frame.
        self._layout = {
            m: (feature_channel(m), self.tensor_shape(m), self.dimension(m))
            for m in self.modalities
        }

    @property
    def emits_amplitude(self) -> bool:
        """Whether ``<modality>_amplitude`` channels are emitted (config ``amplitude``)."""
        return self.config.amplitude == "channel"

    @property
    def output_channels(self) -> Mapping[str, ChannelInfo]:
        rate = self.config.frame_rate_hz
        out = {}
        for m in self.modalities:
            out[_code_channel(m)] = ChannelInfo((self.n_atoms(m),), "1", rate)
            if self.emits_amplitude:
                out[_amplitude_channel(m)] = ChannelInfo((len(AMPLITUDE_FEATURES),), "1", rate)
        return out

    # -- streaming -----------------------------------------------------------------------

    def _rows(
        self, batch: SampleBatch, modality: Modality
    ) -> tuple[NDArray[np.float64], NDArray[np.bool_]]:
        name, shape, dimension = self._layout[modality]
        if name not in batch.channels:
            raise ValueError(
                f"sparse-coding is configured for {list(self.modalities)} but the input lacks "
                f"{name!r}; got {sorted(batch.channels)}"
            )
        tensors = batch.channels[name]
        if tensors.shape[1:] != shape:
            raise ValueError(f"{name!r} tensors have shape {tensors.shape[1:]}, expected {shape}")
        rows = tensors.reshape(tensors.shape[0], dimension)
        ok: NDArray[np.bool_] = np.all(np.isfinite(rows), axis=1)
        if name in batch.valid:
            ok &= batch.valid[name]
        if ok.all():  # the usual case: nothing to zero
            return rows, ok
        return np.where(ok[:, np.newaxis], rows, 0.0), ok

    def update(self, batch: SampleBatch) -> SampleBatch:
        codes: dict[str, NDArray[np.float64]] = {}
        valid: dict[str, NDArray[np.bool_]] = {}
        for m in self.modalities:
            rows, ok = self._rows(batch, m)
            codes[_code_channel(m)] = self._encoders[m](rows, ok)
            valid[_code_channel(m)] = ok
            if self.emits_amplitude:
                codes[_amplitude_channel(m)] = amplitude_features(
                    rows, ok, self.amplitude_references[m]
                )
                valid[_amplitude_channel(m)] = ok
        return SampleBatch(batch.timestamps_s, codes, valid)

    # -- learning --------------------------------------------------------------------------

    def fit(self, batches: Sequence[SampleBatch]) -> None:
        """Learn one dictionary per modality from feature batches (``emd-features`` output).

        Invalid, non-finite and constant tensors are left out. The median centred norm of
        the tensors used becomes the modality's amplitude reference.

        Raises
        ------
        ValueError
            If a modality has fewer than 2 usable tensors.
        """
        if not batches:
            raise ValueError("fit needs at least one batch of feature tensors")
        stats: dict[str, Any] = {}
        learned: dict[Modality, NDArray[np.float64]] = {}
        references: dict[Modality, float] = {}
        for m in self.modalities:
            parts = [self._rows(b, m) for b in batches]
            rows = np.concatenate([p[0] for p in parts])
            ok = np.concatenate([p[1] for p in parts])
            z, flat = normalise_rows(rows)
            references[m] = amplitude_reference(rows[ok & ~flat])
            learned[m], stats[m] = learn_dictionary(
                z[ok & ~flat],
                self.n_atoms(m),
                self.penalty(m),
                init=self.dictionaries[m],
                seed=self._seed,
                epochs=self.config.fit_epochs,
                batch_size=self.config.fit_batch_size,
            )
        self.dictionaries = learned
        self.amplitude_references = references
        self.fitted = True
        self.fit_stats = stats
        self._refresh()

    def training_report(self) -> dict[str, Any]:
        """What the last fit did (:class:`hapticframe.kinds.Trainable`): per modality the
        dictionary learner's statistics and the amplitude reference; empty before a fit."""
        if not self.fitted:
            return {}
        return {
            "modalities": {
                m: {**dict(self.fit_stats.get(m, {})),
                    "amplitude_reference": self.amplitude_references[m]}
                for m in self.modalities
            },
        }

    # -- persistence ---------------------------------------------------------------------

    def metadata(self) -> dict[str, Any]:
        """Settings and versions stored beside the dictionaries."""
        return {
            "format": DICTIONARY_FORMAT,
            "format_version": _FORMAT_VERSION,
            "modalities": list(self.modalities),
            "atoms": {m: self.n_atoms(m) for m in self.modalities},
            "tensor_shapes": {m: list(self.tensor_shape(m)) for m in self.modalities},
            "lambda_scale": self.config.lambda_scale,
            "lambda": {m: self.penalty(m) for m in self.modalities},
            "normalisation": "each flattened tensor centred and scaled to unit l2 norm",
            "amplitude": {
                "mode": self.config.amplitude,
                "features": list(AMPLITUDE_FEATURES),
                "reference": {m: self.amplitude_references[m] for m in self.modalities},
            },
            "encoder": {
                "objective": "0.5 ||z - D^T u||^2 + lambda ||u||_1, z centred and unit-norm",
                "solver": "coordinate descent on the Gram matrix, tol 1e-8 (numba), or "
                "sklearn.decomposition.sparse_encode(algorithm='lasso_cd', alpha=lambda)",
                "backend": self.config.encoder,
            },
            "fitted": self.fitted,
            "fit": {
                "epochs": self.config.fit_epochs,
                "batch_size": self.config.fit_batch_size,
                "seed": self._seed,
                "stats": self.fit_stats,
            },
            "versions": {
                "hapticframe": _version_of("hapticframe"),
                "numpy": np.__version__,
                "scikit-learn": _version_of("scikit-learn"),
                "python": platform.python_version(),
            },
        }

    def save(self, path: str | Path) -> tuple[Path, Path]:
        """Write ``PATH.npz`` (the dictionaries) and ``PATH.json`` (metadata); return both.

        ``PATH`` may be an existing directory (as ``hapticframe train`` passes one): the
        files are then ``dictionaries.npz`` and ``dictionaries.json`` inside it.
        """
        base = _stem(path)
        arrays, meta = base.with_suffix(".npz"), base.with_suffix(".json")
        payload = {f"{m}_dictionary": self.dictionaries[m] for m in self.modalities}
        payload.update(
            {f"{m}_amplitude_reference": np.array(self.amplitude_references[m])
             for m in self.modalities}
        )  # fmt: skip
        # numpy's stub types **kwds as if a key could be `allow_pickle`; none of these names is.
        save_npz(arrays, compressed=False, **payload)
        atomic_write(meta, json.dumps(self.metadata(), indent=2, allow_nan=False) + "\n")
        return arrays, meta

    def load(self, path: str | Path) -> None:
        """Read dictionaries written by :meth:`save` (``PATH.npz`` and ``PATH.json``, or
        ``dictionaries.*`` inside ``PATH`` when it is a directory), checked whole first.

        The ``.json`` must match :class:`_DictionaryFile` (strict types, bounded sizes) and
        this component's config (modalities, sizes, λ); each array's shape and dtype are
        checked from the ``.npz`` headers before reading, then its values: finite, atoms of
        norm in (0, 1] (sklearn's constraint; a zero atom or one dictionary of equal atoms
        encodes nothing), a positive amplitude reference.

        Raises
        ------
        ValueError
            Naming the file: missing, empty, truncated, another format, metadata that
            breaks the schema, or arrays that do not fit this component's config.
        """
        base = _stem(path)
        meta_path, arrays_path = base.with_suffix(".json"), base.with_suffix(".npz")
        if not meta_path.exists():
            raise ValueError(
                f"no dictionaries at {path} (neither a directory holding dictionaries.json and "
                "dictionaries.npz nor the stem of such a pair); `hapticframe train` writes them"
            )
        meta = read_json_object(meta_path)
        if meta.get("format") != DICTIONARY_FORMAT:
            raise ValueError(f"{meta_path} is not a {DICTIONARY_FORMAT} file")
        if meta.get("format_version") not in _READABLE_VERSIONS:
            version = str(meta.get("format_version"))[:20]
            raise ValueError(f"{meta_path}: unsupported dictionary format version {version}")
        try:
            record = _DictionaryFile.model_validate(meta)
        except ValidationError as exc:
            raise schema_error(meta_path, exc) from None
        if not np.isclose(record.lambda_scale, self.config.lambda_scale):
            raise ValueError(
                f"{meta_path}: dictionaries were learned with lambda_scale "
                f"{record.lambda_scale}, the config says {self.config.lambda_scale}"
            )
        shapes: dict[str, tuple[int, ...]] = {}
        for m in self.modalities:
            if m not in record.modalities or m not in record.atoms or m not in record.tensor_shapes:
                raise ValueError(f"{meta_path} has no dictionary for {m!r}")
            saved = (record.atoms[m], math.prod(record.tensor_shapes[m]))
            expected = (self.n_atoms(m), self.dimension(m))
            if saved != expected or tuple(record.tensor_shapes[m]) != self.tensor_shape(m):
                raise ValueError(
                    f"{meta_path}: the {m} dictionary has shape {saved} for tensors "
                    f"{tuple(record.tensor_shapes[m])}; the config expects shape {expected} "
                    f"for {self.tensor_shape(m)} ({m}_atoms, {m}_shape)"
                )
            shapes[f"{m}_dictionary"] = expected
            shapes[f"{m}_amplitude_reference"] = ()
        # The file may hold more modalities than configured: its budget counts all of them.
        declared = {f"{m}_dictionary": (record.atoms[m], math.prod(record.tensor_shapes[m]))
                    for m in record.atoms if m in record.tensor_shapes}
        budget = npz_budget({**declared, **shapes})
        # Version 1 files predate the amplitude channel: unit reference.
        optional = [k for k in shapes if k.endswith("_amplitude_reference")]
        arrays = read_npz_arrays(arrays_path, shapes, optional=optional, max_bytes=budget)
        loaded: dict[Modality, NDArray[np.float64]] = {}
        references: dict[Modality, float] = {}
        for m in self.modalities:
            d = arrays[f"{m}_dictionary"]
            norms = np.linalg.norm(d, axis=1)
            if (norms <= _MIN_ATOM_NORM).any() or (norms > 1.0 + 1e-6).any():
                bad = int(np.count_nonzero((norms <= _MIN_ATOM_NORM) | (norms > 1.0 + 1e-6)))
                raise ValueError(
                    f"{arrays_path}: {m}_dictionary has {bad} atom(s) of zero norm or norm "
                    "above 1; learned atoms have norms in (0, 1]"
                )
            if d.shape[0] > 1 and np.all(d == d[0]):
                raise ValueError(
                    f"{arrays_path}: every atom of {m}_dictionary is the same, so the codes "
                    "would carry one number"
                )
            ref = float(arrays.get(f"{m}_amplitude_reference", np.array(1.0)))
            if not ref > 0:
                raise ValueError(
                    f"{arrays_path}: {m}_amplitude_reference must be positive, got {ref}"
                )
            loaded[m] = d
            references[m] = ref
        self.dictionaries = loaded
        self.amplitude_references = references
        self.fitted = record.fitted
        stats = (record.fit or {}).get("stats")
        self.fit_stats = dict(stats) if isinstance(stats, dict) else {}
        self._refresh()


_MIN_ATOM_NORM = 1e-8
#: Most values one saved dictionary may declare (80 MB of float64; the thesis's pac
#: dictionary holds 200 x 176).
_MAX_DICTIONARY_VALUES = 10_000_000
_Count = Annotated[int, Field(ge=1, le=100_000)]


class _DictionaryFile(BaseModel):
    """The ``.json`` beside saved dictionaries (format versions 1 and 2).

    Strict JSON types; fields this reader does not use are ignored (version 1 files).
    """

    model_config = ConfigDict(strict=True, extra="ignore", frozen=True)

    format: Literal["hapticframe-sparse-dictionaries"]
    format_version: Literal[1, 2]
    modalities: list[Modality] = Field(min_length=1, max_length=3)
    atoms: dict[Modality, _Count]
    tensor_shapes: dict[Modality, Annotated[list[_Count], Field(min_length=2, max_length=2)]]
    lambda_scale: Annotated[float, Field(gt=0, allow_inf_nan=False)]
    fitted: bool = False
    fit: dict[str, Any] | None = None

    @model_validator(mode="after")
    def _bounded(self) -> _DictionaryFile:
        for m, shape in self.tensor_shapes.items():
            size = self.atoms.get(m, 1) * math.prod(shape)
            if size > _MAX_DICTIONARY_VALUES:
                raise ValueError(
                    f"the {m} dictionary would hold {size:.3g} values; the limit is "
                    f"{_MAX_DICTIONARY_VALUES:.3g}"
                )
        return self



def _stem(path: str | Path) -> Path:
    """The file stem of a dictionary pair: ``PATH``, or ``PATH/dictionaries`` for a directory."""
    base = Path(path)
    return base / "dictionaries" if base.is_dir() else base
