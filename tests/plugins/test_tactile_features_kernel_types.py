"""Arguments of any numeric type reach the compiled kernels as one type, so none recompiles.

numba compiles a specialisation per combination of argument types; before the casts at the
public boundary, ``emd(x, 8, sd_threshold=0, residue_ratio=0)`` (ints) cost a fresh compile
of 11-70 s. Each test runs the float call first, then the same call with other types, and
requires the same numbers and no new signature on the kernel's dispatcher.
"""

from __future__ import annotations

import numpy as np
import pytest

from hapticframe_tactile_features import emd
from hapticframe_tactile_features._emd import numba_available
from hapticframe_tactile_features._validation import as_count, as_real

needs_numba = pytest.mark.skipif(not numba_available(), reason="numba is not installed")


def _signal(n: int = 256) -> np.ndarray:
    t = np.linspace(0.0, 1.0, n)
    noise = 0.2 * np.random.default_rng(3).standard_normal(n)
    return np.sin(2 * np.pi * 40 * t) + 0.5 * np.sin(2 * np.pi * 6 * t) + noise


EMD_VARIANTS = [
    {"sd_threshold": 0, "residue_ratio": 0},
    {"max_imfs": np.int64(8), "max_sifts": np.int32(10), "n_mirror": np.uint8(2)},
    {"max_imfs": 8.0, "max_sifts": 10.0, "sd_threshold": np.float32(0.0)},
]


@pytest.mark.parametrize("backend", ["numpy", pytest.param("numba", marks=needs_numba)])
def test_emd_gives_the_same_decomposition_for_any_numeric_argument_type(backend: str) -> None:
    x = _signal()
    floats = {"max_imfs": 8, "sd_threshold": 0.0, "max_sifts": 10, "residue_ratio": 0.0}
    reference = emd(x, backend=backend, **floats)
    assert reference.n_found > 1
    for variant in EMD_VARIANTS:
        got = emd(x, backend=backend, **{**floats, **variant})
        np.testing.assert_array_equal(got.imfs, reference.imfs)
        np.testing.assert_array_equal(got.sift_counts, reference.sift_counts)
    # Integer samples, a list and a strided view are the same float64 signal.
    grid = np.round(1000 * x)
    reference = emd(grid, backend=backend, **floats)
    for signal in (grid.astype(np.int64), grid.tolist(), np.repeat(grid, 2)[::2]):
        np.testing.assert_array_equal(emd(signal, backend=backend, **floats).imfs, reference.imfs)


@needs_numba
def test_emd_never_adds_a_kernel_signature() -> None:
    from hapticframe_tactile_features._emd_kernel import emd_kernel

    x = _signal()
    emd(x, 8, sd_threshold=0.0, residue_ratio=0.0, backend="numba")
    compiled = list(emd_kernel.signatures)
    for variant in EMD_VARIANTS:
        emd(x, **{"max_imfs": 8, **variant}, backend="numba")
    emd(x.astype(np.float32)[::-1], 8, backend="numba")
    assert list(emd_kernel.signatures) == compiled


@needs_numba
def test_lasso_encoders_never_add_a_kernel_signature() -> None:
    pytest.importorskip("sklearn")
    from hapticframe_tactile_features._lasso_kernel import encode_batch, normalise_encode_batch
    from hapticframe_tactile_features._sparse import (
        encode_rows,
        encode_tensors,
        normalise_rows,
        random_dictionary,
    )

    rng = np.random.default_rng(5)
    dictionary = random_dictionary(12, 9, rng)
    gram = dictionary @ dictionary.T
    rows = rng.standard_normal((4, 9))
    z, flat = normalise_rows(rows)
    ok = np.array([True, True, False, True])
    lam = 0.25  # exact in float32, so np.float32(lam) is the same penalty

    codes = encode_rows(z, dictionary, lam, skip=flat, max_iter=1000, backend="numba")
    fused = encode_tensors(rows, ok, dictionary, lam, gram=gram, max_iter=1000, backend="numba")
    assert np.count_nonzero(codes) > 0 and np.count_nonzero(fused) > 0
    compiled = (list(encode_batch.signatures), list(normalise_encode_batch.signatures))

    fortran_d = np.asfortranarray(dictionary)
    again = encode_rows(
        np.asfortranarray(z),
        fortran_d,
        np.float32(lam),
        skip=flat.astype(np.int8).tolist(),
        max_iter=np.int32(1000),
        backend="numba",
    )
    np.testing.assert_array_equal(again, codes)
    again = encode_tensors(
        rows.T.copy().T,  # Fortran order
        ok.astype(int),
        fortran_d,
        lam,
        gram=np.asfortranarray(gram),
        max_iter=1000.0,
        tol=np.float32(1e-8).item(),
        backend="numba",
    )
    np.testing.assert_array_equal(again, fused)
    assert (list(encode_batch.signatures), list(normalise_encode_batch.signatures)) == compiled


def test_scalar_casts() -> None:
    assert as_count("n", np.int16(3)) == 3 and type(as_count("n", np.int16(3))) is int
    assert as_count("n", 4.0) == 4 and type(as_count("n", 4.0)) is int
    assert type(as_real("x", 0)) is float and as_real("x", np.float32(0.5)) == 0.5
    for bad in (2.5, float("nan"), float("inf")):
        with pytest.raises(ValueError, match="n must be an integer"):
            as_count("n", bad)
    for wrong in (True, "3", None, np.bool_(False)):
        with pytest.raises(TypeError, match="n must be an integer"):
            as_count("n", wrong)
        with pytest.raises(TypeError, match="x must be a real number"):
            as_real("x", wrong)
    with pytest.raises(ValueError, match="max_sifts must be an integer"):
        emd(_signal(), 8, max_sifts=2.5)
    with pytest.raises(TypeError, match="sd_threshold must be a real number"):
        emd(_signal(), 8, sd_threshold="0.1")  # type: ignore[arg-type]
