"""Sparse coding functions: normalisation, lasso encoding, dictionary learning.

The objective per vector is Mairal et al.'s (JMLR 2010) ``0.5 ||x - D^T u||^2 + λ ||u||_1``
with unit-norm atoms (the rows of ``D``), and λ = 1.2 / sqrt(m) for m-dimensional vectors.
That λ presumes each vector is centred and of unit ℓ2 norm, so :func:`normalise_rows` is
applied before learning and before encoding; a vector that is constant to rounding has no
direction and gets the all-zero code.

Encoders (``backend``): our coordinate descent on the Gram matrix, compiled with numba
(:mod:`._lasso_kernel`; ≈ 30 µs a code against ≈ 0.4 ms of scikit-learn per-call overhead),
or :func:`sklearn.decomposition.sparse_encode` (the reference, used without numba). Both
minimise the same objective with the same stopping rule; the tests hold ours to
scikit-learn's codes.

scikit-learn traps avoided here (``shared/notes/perception.md`` §2.1):

- ``MiniBatchDictionaryLearning`` and ``SparseCoder`` transform with OMP by default, which
  ignores α and keeps m/10 non-zeros; the reference path calls
  :func:`sklearn.decomposition.sparse_encode` with ``algorithm="lasso_cd"`` and
  ``alpha=λ`` explicitly, which solves the objective above (sklearn divides α by m inside
  only to cancel its own Lasso's 1/(2m) scaling).
- Encoding is done one vector at a time, with one Gram matrix per dictionary: batched
  coordinate descent starts from BLAS products whose last bits depend on the batch size,
  and the solver's stopping test can then flip, so only per-row encoding makes a chunked
  stream equal the batch path exactly (the numba kernel solves row by row too).

scikit-learn and numba are imported inside the functions that need them.
"""

from __future__ import annotations

import importlib.util
import warnings
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ._validation import as_count, as_real

__all__ = [
    "AMPLITUDE_FEATURES",
    "ENCODE_TOL",
    "TensorEncoder",
    "amplitude_features",
    "amplitude_reference",
    "encode_rows",
    "encode_tensors",
    "learn_dictionary",
    "normalise_rows",
    "random_dictionary",
    "sparsity_penalty",
]

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]

#: Coordinate-descent tolerance (scikit-learn's ``sparse_encode`` fixes the same 1e-8).
ENCODE_TOL = 1e-8

# A centred norm within this many ulps of the vector's magnitude is rounding: "constant".
_FLAT_ULPS = 64.0


def sparsity_penalty(dimension: int, scale: float = 1.2) -> float:
    """λ = scale / sqrt(m) (Mairal et al. 2010; the thesis's setting with scale 1.2)."""
    if dimension < 1:
        raise ValueError("dimension must be at least 1")
    return float(scale / np.sqrt(dimension))


def normalise_rows(x: FloatArray) -> tuple[FloatArray, BoolArray]:
    """Centre each row and scale it to unit ℓ2 norm.

    Returns
    -------
    z : (n, m) float64
        Normalised rows; all-zero where the row is flat.
    flat : (n,) bool
        Rows that are constant to within 64 ulps of their magnitude (including all-zero
        rows); they have no direction to encode.
    """
    x = np.asarray(x, dtype=np.float64)
    if x.ndim != 2:
        raise ValueError(f"expected (n, m) rows, got shape {x.shape}")
    if not np.isfinite(x).all():
        raise ValueError("rows to normalise hold NaN or infinity")
    centred = x - x.mean(axis=1, keepdims=True)
    norm = np.linalg.norm(centred, axis=1)
    magnitude = np.abs(x).max(axis=1, initial=0.0) * np.sqrt(x.shape[1])
    flat = norm <= _FLAT_ULPS * np.finfo(np.float64).eps * magnitude
    safe = np.where(flat, 1.0, norm)
    z = np.where(flat[:, np.newaxis], 0.0, centred / safe[:, np.newaxis])
    return z, flat


#: What :func:`amplitude_features` returns per row, in column order.
AMPLITUDE_FEATURES: tuple[str, str] = ("log_norm", "mean")


def amplitude_reference(rows: FloatArray) -> float:
    """Median centred ℓ2 norm of finite, non-flat rows: the scale of :func:`amplitude_features`.

    Returns 1.0 when no row qualifies (nothing to learn a scale from).
    """
    x = np.asarray(rows, dtype=np.float64)
    if x.ndim != 2:
        raise ValueError(f"expected (n, m) rows, got shape {x.shape}")
    x = x[np.isfinite(x).all(axis=1)]
    if x.shape[0] == 0:
        return 1.0
    _, flat = normalise_rows(x)
    norms = np.linalg.norm(x - x.mean(axis=1, keepdims=True), axis=1)[~flat]
    return float(np.median(norms)) if norms.size else 1.0


def amplitude_features(rows: FloatArray, ok: BoolArray, reference: float) -> FloatArray:
    """What :func:`normalise_rows` discards, as two bounded-growth numbers per row.

    Columns (:data:`AMPLITUDE_FEATURES`): ``log1p(norm / reference) - log 2``, with ``norm``
    the row's centred ℓ2 norm, and ``asinh(mean / reference)``. Both are 0 for a row of
    typical size (``norm == reference``) and zero mean, so a zero-filled (missing) amplitude
    reads as "typical"; logarithmic growth keeps a hard press from dwarfing the rest. Rows
    where ``ok`` is False get zeros.

    Parameters
    ----------
    rows : (n, m) float64
        Flattened tensors; rows where ``ok`` is False may hold anything (NaN included).
    ok : (n,) bool
    reference : float
        Positive scale, e.g. :func:`amplitude_reference` of training rows.
    """
    if not (np.isfinite(reference) and reference > 0):
        raise ValueError(f"amplitude reference must be positive and finite, got {reference}")
    x = np.asarray(rows, dtype=np.float64)
    if x.ndim != 2:
        raise ValueError(f"expected (n, m) rows, got shape {x.shape}")
    use = np.asarray(ok, dtype=bool)
    safe = np.where(use[:, np.newaxis], x, 0.0)
    # Divide by the largest magnitude first so that huge rows neither overflow the mean nor
    # the squares of the norm; both are rescaled in the log domain.
    peak = np.abs(safe).max(axis=1, initial=0.0)
    unit = np.where(peak > 0, peak, 1.0)
    scaled = safe / unit[:, np.newaxis]
    mean_scaled = scaled.mean(axis=1)
    norm_scaled = np.linalg.norm(scaled - mean_scaled[:, np.newaxis], axis=1)
    log_norm = np.where(
        norm_scaled > 0,
        np.logaddexp(0.0, np.log(np.maximum(norm_scaled, 1e-300)) + np.log(unit)
                     - np.log(reference)),
        0.0,
    ) - np.log(2.0)  # log1p(norm / reference) - log 2, computed without overflow
    with np.errstate(over="ignore"):
        mean_rel = np.clip(mean_scaled * (unit / reference), -1e300, 1e300)
    out = np.column_stack([log_norm, np.arcsinh(mean_rel)])
    out[~use] = 0.0
    return out


def random_dictionary(n_atoms: int, dimension: int, rng: np.random.Generator) -> FloatArray:
    """``n_atoms`` unit-norm atoms with Gaussian entries, drawn from ``rng`` (rows)."""
    atoms = rng.standard_normal((n_atoms, dimension))
    return atoms / np.linalg.norm(atoms, axis=1, keepdims=True)


def encode_rows(
    z: FloatArray,
    dictionary: FloatArray,
    alpha: float,
    *,
    skip: BoolArray | None = None,
    max_iter: int = 1000,
    gram: FloatArray | None = None,
    tol: float = ENCODE_TOL,
    backend: str = "auto",
) -> FloatArray:
    """Lasso codes of normalised rows ``z`` over ``dictionary`` (atoms as rows).

    Parameters
    ----------
    z : (n, m) float64
        Centred, unit-norm rows (:func:`normalise_rows`).
    dictionary : (k, m) float64
    alpha : float
        λ of the objective ``0.5 ||z - D^T u||^2 + λ ||u||_1``.
    skip : (n,) bool, optional
        Rows that get the zero code without solving (flat or invalid rows).
    max_iter : int
        Coordinate-descent iteration cap.
    gram : (k, k) float64, optional
        ``dictionary @ dictionary.T``, precomputed by the caller to save time.
    tol : float
        Stopping tolerance of the coordinate descent (step and duality gap, as in
        scikit-learn; ``sparse_encode`` fixes it at 1e-8). Used by the numba backend only.
    backend : {"auto", "numba", "sklearn"}
        ``"numba"``: our coordinate descent (:mod:`._lasso_kernel`), ≈ 30× faster per
        call; ``"sklearn"``: :func:`sklearn.decomposition.sparse_encode`; ``"auto"``
        takes numba when it is installed. Both solve the same problem to the tolerance.

    Returns
    -------
    (n, k) float64

    Warns
    -----
    RuntimeWarning
        (numba backend) when a row ran out of ``max_iter`` sweeps before converging.
    """
    d = np.ascontiguousarray(dictionary, dtype=np.float64)
    g = d @ d.T if gram is None else np.ascontiguousarray(gram, dtype=np.float64)
    # One type per argument, so that the compiled kernel is never re-specialised (a compile).
    alpha = as_real("alpha", alpha)
    max_iter = as_count("max_iter", max_iter)
    tol = as_real("tol", tol)
    if _use_numba(backend):
        from ._lasso_kernel import encode_batch

        rows = np.ascontiguousarray(z, dtype=np.float64)
        skipped = (
            np.zeros(rows.shape[0], dtype=bool)
            if skip is None
            else np.ascontiguousarray(skip, dtype=bool)
        )
        codes = np.empty((rows.shape[0], d.shape[0]))
        unconverged = encode_batch(rows, d, g, alpha, skipped, max_iter, tol, codes)
        if unconverged:
            warnings.warn(
                f"lasso encoding: {unconverged} of {rows.shape[0]} rows did not converge in "
                f"{max_iter} sweeps (raise encode_max_iter)",
                RuntimeWarning,
                stacklevel=2,
            )
        return codes
    from sklearn.decomposition import sparse_encode

    codes = np.zeros((z.shape[0], d.shape[0]))
    for i in range(z.shape[0]):
        if skip is not None and skip[i]:
            continue
        row = np.ascontiguousarray(z[i : i + 1], dtype=np.float64)
        codes[i] = sparse_encode(
            row,
            d,
            gram=g,
            algorithm="lasso_cd",
            alpha=alpha,
            max_iter=max_iter,
            check_input=False,
        )[0]
    return codes


def encode_tensors(
    rows: FloatArray,
    ok: BoolArray,
    dictionary: FloatArray,
    alpha: float,
    *,
    gram: FloatArray,
    max_iter: int = 1000,
    tol: float = ENCODE_TOL,
    backend: str = "auto",
) -> FloatArray:
    """Normalise raw flattened tensors and encode them: :func:`normalise_rows` then
    :func:`encode_rows`, in one compiled call on the numba backend.

    Parameters
    ----------
    rows : (n, m) float64
        Flattened tensors; rows where ``ok`` is False may hold anything finite.
    ok : (n,) bool
        Rows to encode; the others, and flat rows, get the zero code.
    dictionary, alpha, gram, max_iter, tol, backend
        As for :func:`encode_rows` (``gram`` is required here).
    """
    encoder = TensorEncoder(dictionary, alpha, gram=gram, max_iter=max_iter, tol=tol,
                            backend=backend)
    return encoder(rows, ok)


class TensorEncoder:
    """:func:`encode_tensors` with its settings checked and its arrays prepared once.

    A streaming coder encodes one row per modality every 10 ms; checking the settings,
    resolving the backend and making the dictionary contiguous on every call cost more than
    a well-converged encode, so the coder builds one of these per dictionary.
    """

    def __init__(
        self,
        dictionary: FloatArray,
        alpha: float,
        *,
        gram: FloatArray,
        max_iter: int = 1000,
        tol: float = ENCODE_TOL,
        backend: str = "auto",
    ) -> None:
        self.alpha = as_real("alpha", alpha)
        self.max_iter = as_count("max_iter", max_iter)
        self.tol = as_real("tol", tol)
        self.backend = backend
        self.numba = _use_numba(backend)
        self.dictionary = np.ascontiguousarray(dictionary, dtype=np.float64)
        self.gram = np.ascontiguousarray(gram, dtype=np.float64)
        self._kernel: Any = None
        if self.numba:
            from ._lasso_kernel import normalise_encode_batch

            self._kernel = normalise_encode_batch

    def __call__(self, rows: FloatArray, ok: BoolArray) -> FloatArray:
        """Codes (n, k) of ``rows`` (n, m): see :func:`encode_tensors`."""
        if not self.numba:
            z, flat = normalise_rows(rows)
            return encode_rows(z, self.dictionary, self.alpha, skip=flat | ~ok,
                               max_iter=self.max_iter, gram=self.gram, backend=self.backend)
        x = np.ascontiguousarray(rows, dtype=np.float64)
        codes = np.empty((x.shape[0], self.dictionary.shape[0]))
        unconverged = self._kernel(
            x, np.ascontiguousarray(ok, dtype=bool), self.dictionary, self.gram, self.alpha,
            self.max_iter, self.tol, _FLAT_ULPS, codes,
        )  # fmt: skip
        if unconverged:
            warnings.warn(
                f"lasso encoding: {unconverged} of {x.shape[0]} rows did not converge in "
                f"{self.max_iter} sweeps (raise encode_max_iter)",
                RuntimeWarning,
                stacklevel=3,
            )
        return codes


def _use_numba(backend: str) -> bool:
    if backend == "sklearn":
        return False
    available = importlib.util.find_spec("numba") is not None
    if backend == "numba":
        if not available:
            raise ImportError("backend='numba' needs numba: pip install 'numba>=0.60'")
        return True
    if backend == "auto":
        return available
    raise ValueError(f"backend must be 'auto', 'numba' or 'sklearn', got {backend!r}")


def learn_dictionary(
    z: FloatArray,
    n_atoms: int,
    alpha: float,
    *,
    init: FloatArray,
    seed: int,
    epochs: int = 10,
    batch_size: int = 256,
) -> tuple[FloatArray, dict[str, Any]]:
    """Learn ``n_atoms`` atoms from normalised rows with ``MiniBatchDictionaryLearning``.

    Returns the dictionary (atoms as rows, norms ≤ 1) and fit statistics.
    """
    from sklearn.decomposition import MiniBatchDictionaryLearning

    if z.shape[0] < 2:
        raise ValueError(
            f"need at least 2 non-constant feature vectors to learn from, got {z.shape[0]}"
        )
    learner = MiniBatchDictionaryLearning(
        n_components=n_atoms,
        alpha=alpha,
        max_iter=epochs,
        batch_size=min(batch_size, z.shape[0]),
        dict_init=init,
        random_state=seed,
        # Coordinate descent solves each minibatch's lasso for all rows at once; the default
        # LARS solves row by row and reaches the same objective about 15x slower.
        fit_algorithm="cd",
        transform_algorithm="lasso_cd",  # not the α-ignoring OMP default
        transform_alpha=alpha,
    )
    from sklearn.exceptions import ConvergenceWarning

    # The lasso solves inside a minibatch step are iterates of an alternating scheme and need
    # not be exact; the codes the component emits come from the encoder, which converges.
    # So their convergence warnings are counted in the statistics rather than printed.
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", ConvergenceWarning)
        learner.fit(z)
    for warning in caught:
        if not issubclass(warning.category, ConvergenceWarning):
            warnings.warn_explicit(
                warning.message, warning.category, warning.filename, warning.lineno
            )
    stats = {
        "samples": int(z.shape[0]),
        "epochs_run": int(learner.n_iter_),
        "steps": int(learner.n_steps_),
        "inexact_inner_solves": sum(issubclass(w.category, ConvergenceWarning) for w in caught),
    }
    return np.array(learner.components_, dtype=np.float64), stats
