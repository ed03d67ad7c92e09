"""Sparse coding functions: normalisation, lasso encoding, dictionary learning.

The objective per vector is Mairal et al.'s (JMLR 2010) ``0.5 ||x - D^T u||^2 + λ ||u||_1``
with unit-norm atoms (the rows of ``D``), and λ = 1.2 / sqrt(m) for m-dimensional vectors.
That λ presumes each vector is centred and of unit ℓ2 norm, so :func:`normalise_rows` is
applied before learning and before encoding; a vector that is constant to rounding has no
direction and gets the all-zero code.

scikit-learn traps avoided here (``shared/notes/perception.md`` §2.1):

- ``MiniBatchDictionaryLearning`` and ``SparseCoder`` transform with OMP by default, which
  ignores α and keeps m/10 non-zeros; :func:`encode_rows` calls
  :func:`sklearn.decomposition.sparse_encode` with ``algorithm="lasso_cd"`` and
  ``alpha=λ`` explicitly, which solves the objective above (sklearn divides α by m inside
  only to cancel its own Lasso's 1/(2m) scaling).
- Encoding is done one vector at a time, with one Gram matrix per dictionary: batched
  coordinate descent starts from BLAS products whose last bits depend on the batch size,
  and the solver's stopping test can then flip, so only per-row encoding makes a chunked
  stream equal the batch path exactly.

scikit-learn is imported inside the functions that need it.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

__all__ = [
    "encode_rows",
    "learn_dictionary",
    "normalise_rows",
    "random_dictionary",
    "sparsity_penalty",
]

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]

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

    Returns
    -------
    (n, k) float64
    """
    from sklearn.decomposition import sparse_encode

    d = np.ascontiguousarray(dictionary, dtype=np.float64)
    g = d @ d.T if gram is None else gram
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
        transform_algorithm="lasso_cd",  # not the α-ignoring OMP default
        transform_alpha=alpha,
    )
    learner.fit(z)
    stats = {
        "samples": int(z.shape[0]),
        "epochs_run": int(learner.n_iter_),
        "steps": int(learner.n_steps_),
    }
    return np.array(learner.components_, dtype=np.float64), stats
