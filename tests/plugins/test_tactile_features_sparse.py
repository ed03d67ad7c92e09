"""Sparse coding: normalisation, λ, lasso optimality, learning, save/load, streaming."""

from __future__ import annotations

import json
import subprocess
import sys
import warnings
from pathlib import Path

import numpy as np
import pytest

from hapticframe.kinds import BuildContext, SampleBatch
from hapticframe_bench import synthetic_biotac_frames
from hapticframe_tactile_features._config import SparseCodingConfig
from hapticframe_tactile_features._emd import numba_available
from hapticframe_tactile_features._sparse import (
    encode_rows,
    encode_tensors,
    learn_dictionary,
    normalise_rows,
    random_dictionary,
    sparsity_penalty,
)
from hapticframe_tactile_features._sparse_coding import SparseCodingExtractor

pytest.importorskip("sklearn")

# Both lasso encoders: scikit-learn's sparse_encode (the reference) and our coordinate
# descent compiled with numba (the default when numba is installed).
needs_numba = pytest.mark.skipif(not numba_available(), reason="numba is not installed")
ENCODERS = ["sklearn", pytest.param("numba", marks=needs_numba)]


def _coder(seed: int = 0, **config: object) -> SparseCodingExtractor:
    return SparseCodingExtractor(
        SparseCodingConfig(**config), BuildContext("codes", np.random.default_rng(seed))
    )


def _sparse_mixtures(
    rng: np.random.Generator, atoms: np.ndarray, n: int, active: int = 3
) -> np.ndarray:
    """Rows mixing ``active`` random atoms with weights of either sign, plus 1 % noise."""
    codes = np.zeros((n, atoms.shape[0]))
    for row in codes:
        chosen = rng.choice(atoms.shape[0], active, replace=False)
        row[chosen] = rng.uniform(0.5, 1.5, active) * rng.choice([-1.0, 1.0], active)
    return codes @ atoms + 0.01 * rng.standard_normal((n, atoms.shape[1]))


def _tensor_batch(
    rng: np.random.Generator, n: int, shapes: dict[str, tuple[int, int]]
) -> SampleBatch:
    return SampleBatch(
        (1 + np.arange(n)) / 100.0,
        {name: rng.standard_normal((n, *shape)) for name, shape in shapes.items()},
    )


_SHAPES = {"pac_imfs": (8, 22), "pdc_imfs": (5, 5), "electrodes_window": (19, 5)}


def test_thesis_penalties() -> None:
    assert sparsity_penalty(176) == pytest.approx(0.0905, abs=5e-5)
    assert sparsity_penalty(25) == pytest.approx(0.240)
    assert sparsity_penalty(95) == pytest.approx(0.1231, abs=5e-5)
    coder = _coder()
    assert {m: round(coder.penalty(m), 4) for m in coder.modalities} == {
        "pac": 0.0905,
        "pdc": 0.24,
        "electrodes": 0.1231,
    }


def test_normalise_rows_centres_scales_and_flags_flat_rows() -> None:
    rng = np.random.default_rng(0)
    x = rng.standard_normal((4, 10)) * np.array([[1.0], [1e9], [1e-12], [3.0]])
    x[3] = 7.0
    z, flat = normalise_rows(x)
    assert flat.tolist() == [False, False, False, True]
    assert np.allclose(z[:3].mean(axis=1), 0.0, atol=1e-15)
    assert np.allclose(np.linalg.norm(z[:3], axis=1), 1.0)
    assert np.all(z[3] == 0.0)
    # Scale and offset do not change the normalised vector.
    z2, _ = normalise_rows(np.vstack([5e8 * x[0] + 123.0]))
    assert np.allclose(z2[0], z[0], atol=1e-12)
    with pytest.raises(ValueError):
        normalise_rows(np.array([[np.nan, 1.0]]))


@pytest.mark.parametrize("encoder", ENCODERS)
def test_lasso_codes_satisfy_the_optimality_conditions_at_the_thesis_lambda(encoder: str) -> None:
    # KKT conditions of min 0.5||z - D^T u||^2 + λ||u||_1: on the support the correlation
    # of each atom with the residual equals λ·sign(u); off it, it is at most λ. OMP (the
    # scikit-learn default transform) would ignore λ and fail this.
    rng = np.random.default_rng(2)
    dictionary = random_dictionary(60, 25, rng)
    z, _ = normalise_rows(_sparse_mixtures(rng, dictionary, 20))
    lam = sparsity_penalty(25)
    codes = encode_rows(z, dictionary, lam, max_iter=5000, backend=encoder)
    for row, code in zip(z, codes, strict=True):
        correlation = dictionary @ (row - code @ dictionary)
        support = code != 0
        assert support.any()
        assert np.abs(correlation[support] - lam * np.sign(code[support])).max() < 1e-4
        assert np.abs(correlation[~support]).max() <= lam + 1e-4


def test_learned_dictionary_reconstructs_sparse_data_at_the_thesis_lambda() -> None:
    rng = np.random.default_rng(3)
    m, true_atoms, k = 95, 30, 60  # electrode-sized vectors
    truth = random_dictionary(true_atoms, m, rng)
    train, _ = normalise_rows(_sparse_mixtures(rng, truth, 800))
    test, _ = normalise_rows(_sparse_mixtures(rng, truth, 200))
    lam = sparsity_penalty(m)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # sklearn's early-stopping notices
        learned, stats = learn_dictionary(
            train, k, lam, init=random_dictionary(k, m, rng), seed=0, epochs=5
        )
    assert learned.shape == (k, m) and stats["samples"] == 800
    assert np.linalg.norm(learned, axis=1).max() <= 1.0 + 1e-9

    def quality(dictionary: np.ndarray) -> tuple[float, float]:
        codes = encode_rows(test, dictionary, lam)
        error = np.linalg.norm(test - codes @ dictionary, axis=1)  # rows have unit norm
        return float(error.mean()), float((codes != 0).sum(axis=1).mean())

    error, nonzeros = quality(learned)
    random_error, _ = quality(random_dictionary(k, m, rng))
    # Measured: mean error 0.237 and 4.2 non-zeros per code with the learned atoms (lasso
    # shrinkage at λ = 0.123 alone costs ~0.2 on unit vectors of 3 atoms); 0.90 and 11.5
    # non-zeros with random atoms.
    assert error < 0.32
    assert 2.0 <= nonzeros <= 8.0
    assert random_error > 0.7


def test_random_dictionary_before_fit_is_seeded_and_unit_norm() -> None:
    a, b, c = _coder(seed=4), _coder(seed=4), _coder(seed=5)
    assert not a.fitted
    for m in a.modalities:
        assert a.dictionaries[m].shape == (a.n_atoms(m), a.dimension(m))
        assert np.allclose(np.linalg.norm(a.dictionaries[m], axis=1), 1.0)
        assert np.array_equal(a.dictionaries[m], b.dictionaries[m])
        assert not np.array_equal(a.dictionaries[m], c.dictionaries[m])


def test_codes_of_batches_flat_and_invalid_tensors() -> None:
    rng = np.random.default_rng(6)
    coder = _coder(pac_atoms=30, pdc_atoms=20, electrodes_atoms=20)
    batch = _tensor_batch(rng, 6, _SHAPES)
    channels = {k: v.copy() for k, v in batch.channels.items()}
    channels["pac_imfs"][1] = 5.0  # constant: no direction
    channels["pdc_imfs"][2, 0, 0] = np.nan
    valid = {"electrodes_window": np.array([True, True, True, False, True, True])}
    out = coder.update(SampleBatch(batch.timestamps_s, channels, valid))
    assert {k: v.shape for k, v in out.channels.items()} == {
        "pac_code": (6, 30),
        "pdc_code": (6, 20),
        "electrodes_code": (6, 20),
    }
    assert all(np.isfinite(v).all() for v in out.channels.values())
    assert np.all(out.channels["pac_code"][1] == 0) and out.valid["pac_code"][1]
    assert np.all(out.channels["pdc_code"][2] == 0) and not out.valid["pdc_code"][2]
    assert np.all(out.channels["electrodes_code"][3] == 0) and not out.valid["electrodes_code"][3]
    assert np.count_nonzero(out.channels["pac_code"][0]) > 0
    # Codes do not depend on the tensors' scale or offset.
    scaled = SampleBatch(batch.timestamps_s, {k: 1e9 * v + 7.0 for k, v in batch.channels.items()})
    assert np.allclose(
        coder.update(scaled).channels["pdc_code"],
        coder.update(batch).channels["pdc_code"],
        atol=1e-6,
    )


@pytest.mark.parametrize("encoder", ENCODERS)
def test_streaming_equals_batch_exactly(encoder: str) -> None:
    rng = np.random.default_rng(7)
    coder = _coder(pac_atoms=30, pdc_atoms=20, electrodes_atoms=20, encoder=encoder)
    batch = _tensor_batch(rng, 25, _SHAPES)
    whole = coder.transform(batch)
    parts = [coder.update(batch.select(slice(s, s + 4))) for s in range(0, 25, 4)]
    for name, array in whole.channels.items():
        assert np.array_equal(np.concatenate([p.channels[name] for p in parts]), array)


def test_only_configured_modalities_are_encoded() -> None:
    coder = _coder(modalities=["pdc"], pdc_atoms=10)
    batch = _tensor_batch(np.random.default_rng(8), 3, {"pdc_imfs": (5, 5)})
    assert set(coder.update(batch).channels) == {"pdc_code"}
    with pytest.raises(ValueError, match="lacks 'pac_imfs'"):
        _coder(modalities=["pac"]).update(batch)


def test_fit_save_load_round_trip(tmp_path: Path) -> None:
    rng = np.random.default_rng(9)
    config = {"pac_atoms": 12, "pdc_atoms": 8, "electrodes_atoms": 8, "fit_epochs": 2}
    coder = _coder(seed=1, **config)
    before = {m: d.copy() for m, d in coder.dictionaries.items()}
    batches = [_tensor_batch(rng, 150, _SHAPES), _tensor_batch(rng, 150, _SHAPES)]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        coder.fit(batches)
    assert coder.fitted and coder.fit_stats["pac"]["samples"] == 300
    assert not np.array_equal(coder.dictionaries["pac"], before["pac"])
    arrays, meta_path = coder.save(tmp_path / "dictionaries")
    meta = json.loads(meta_path.read_text())
    assert meta["fitted"] and meta["atoms"] == {"pac": 12, "pdc": 8, "electrodes": 8}
    assert meta["lambda"]["pac"] == pytest.approx(1.2 / np.sqrt(176))
    assert meta["versions"]["numpy"] == np.__version__ and meta["versions"]["scikit-learn"]
    with np.load(arrays, allow_pickle=False) as data:
        assert sorted(data.files) == sorted(
            f"{m}_{what}"
            for m in ("pac", "pdc", "electrodes")
            for what in ("dictionary", "amplitude_reference")
        )
    # A component built from the file (another seed) gives the same codes.
    loaded = _coder(seed=99, dictionary_file=str(tmp_path / "dictionaries"), **config)
    assert loaded.fitted
    probe = _tensor_batch(rng, 5, _SHAPES)
    for name, codes in coder.update(probe).channels.items():
        assert np.array_equal(loaded.update(probe).channels[name], codes)


def test_a_directory_holds_the_pair_as_hapticframe_train_passes_one(tmp_path: Path) -> None:
    config = {"pac_atoms": 12, "pdc_atoms": 8, "electrodes_atoms": 8}
    coder = _coder(seed=3, **config)
    target = tmp_path / "codes"
    target.mkdir()
    arrays, meta = coder.save(target)
    assert (arrays, meta) == (target / "dictionaries.npz", target / "dictionaries.json")
    assert arrays.is_file() and meta.is_file()
    loaded = _coder(seed=98, dictionary_file=str(target), **config)
    for m in ("pac", "pdc", "electrodes"):
        assert np.array_equal(loaded.dictionaries[m], coder.dictionaries[m])


def test_load_rejects_mismatched_files(tmp_path: Path) -> None:
    _coder(pac_atoms=12, pdc_atoms=8, electrodes_atoms=8).save(tmp_path / "d")
    with pytest.raises(ValueError, match="shape"):
        _coder(pac_atoms=13, pdc_atoms=8, electrodes_atoms=8, dictionary_file=str(tmp_path / "d"))
    with pytest.raises(ValueError, match="lambda_scale"):
        _coder(
            pac_atoms=12,
            pdc_atoms=8,
            electrodes_atoms=8,
            lambda_scale=1.0,
            dictionary_file=str(tmp_path / "d"),
        )
    (tmp_path / "x.json").write_text(json.dumps({"format": "other"}))
    with pytest.raises(ValueError, match="not a"):
        _coder().load(tmp_path / "x")
    # Before `hapticframe train` has written them: a ValueError (exit 2 from a run), naming
    # what is missing, not a FileNotFoundError.
    with pytest.raises(ValueError, match=r"no dictionaries at .*nowhere"):
        _coder(dictionary_file=str(tmp_path / "nowhere"))


def test_fit_needs_usable_data() -> None:
    coder = _coder(pac_atoms=5, pdc_atoms=5, electrodes_atoms=5)
    with pytest.raises(ValueError):
        coder.fit([])
    flat = SampleBatch(np.array([0.01, 0.02]), {k: np.ones((2, *s)) for k, s in _SHAPES.items()})
    with pytest.raises(ValueError, match="at least 2"):
        coder.fit([flat])


def test_config_and_registration_do_not_import_sklearn() -> None:
    code = (
        "import sys, hapticframe_tactile_features.plugin, hapticframe_tactile_features._config\n"
        "print('sklearn' in sys.modules, 'scipy' in sys.modules)\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.split() == ["False", "False"]
    code = (
        "import sys, hapticframe_tactile_features.plugin, hapticframe_tactile_features._sparse\n"
        "import hapticframe_tactile_features._emd, hapticframe_tactile_features._streaming\n"
        "print('numba' in sys.modules)\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.split() == ["False"]  # numba loads only when a kernel first runs


# -- our lasso encoder against scikit-learn -------------------------------------------------


def _objective(z: np.ndarray, codes: np.ndarray, dictionary: np.ndarray, lam: float) -> np.ndarray:
    return 0.5 * ((z - codes @ dictionary) ** 2).sum(axis=1) + lam * np.abs(codes).sum(axis=1)


def _real_rows_and_dictionary(
    modality: str, n_atoms: int
) -> tuple[np.ndarray, np.ndarray, float]:
    """Normalised emd-features tensors of synthetic BioTac frames and a learned dictionary."""
    from hapticframe_tactile_features._config import EMDFeaturesConfig, feature_channel
    from hapticframe_tactile_features._emd_features import EMDFeatureExtractor

    frames = synthetic_biotac_frames(260, np.random.default_rng(11))
    fx = EMDFeatureExtractor(
        EMDFeaturesConfig(delay_frames=1), BuildContext("fx", np.random.default_rng(0))
    )
    tensors = fx.transform(frames).channels[feature_channel(modality)]  # type: ignore[arg-type]
    z, flat = normalise_rows(tensors.reshape(len(tensors), -1))
    z = z[~flat]
    rng = np.random.default_rng(12)
    lam = sparsity_penalty(z.shape[1])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        dictionary, _ = learn_dictionary(
            z[:200], n_atoms, lam, init=random_dictionary(n_atoms, z.shape[1], rng), seed=0,
            epochs=2,
        )  # fmt: skip
    return z[200:], dictionary, lam


@needs_numba
@pytest.mark.parametrize(
    "case", ["random-pac", "random-pdc", "random-electrodes", "real-pac", "real-pdc"]
)
def test_numba_encoder_matches_sklearn_sparse_encode(case: str) -> None:
    from sklearn.decomposition import sparse_encode
    from sklearn.linear_model import Lasso

    if case.startswith("random"):
        k, m = {"random-pac": (200, 176), "random-pdc": (100, 25), "random-electrodes": (100, 95)}[
            case
        ]
        rng = np.random.default_rng(k + m)
        dictionary = random_dictionary(k, m, rng)
        z, _ = normalise_rows(_sparse_mixtures(rng, dictionary, 12))
        lam = sparsity_penalty(m)
    else:
        z, dictionary, lam = _real_rows_and_dictionary(case.removeprefix("real-"), 60)
        z = z[:12]
    ours = encode_rows(z, dictionary, lam, backend="numba")
    theirs = sparse_encode(z, dictionary, algorithm="lasso_cd", alpha=lam, max_iter=1000)
    # A tightly converged solve of the same problem with scikit-learn's Lasso, whose data
    # term is scaled by 1/(2m): its alpha is λ/m.
    tight = np.array(
        [
            Lasso(alpha=lam / z.shape[1], fit_intercept=False, tol=1e-14, max_iter=100_000)
            .fit(dictionary.T, row)
            .coef_
            for row in z
        ]
    )
    assert np.count_nonzero(ours) > 0
    # Both solvers stop at a duality gap of 1e-8 (ours after an exact solve on the
    # support): measured differences ~1e-9 to scikit-learn, ~1e-15 to the tight solve.
    assert np.abs(ours - theirs).max() < 1e-5
    assert np.abs(ours - tight).max() < 1e-6
    objective_ours = _objective(z, ours, dictionary, lam)
    assert np.all(objective_ours <= _objective(z, theirs, dictionary, lam) + 1e-12)
    assert np.array_equal(ours != 0, np.abs(tight) > 1e-9)


@needs_numba
def test_fused_normalise_and_encode_equals_the_two_steps() -> None:
    rng = np.random.default_rng(13)
    dictionary = random_dictionary(40, 25, rng)
    gram = dictionary @ dictionary.T
    lam = sparsity_penalty(25)
    rows = 1e6 * rng.standard_normal((7, 25)) + 3.0
    rows[2] = 4.0  # flat: zero code
    rows[5] = 1e9 + np.tile([0.0, 1.2e-7], 13)[:25]  # flat to rounding
    ok = np.ones(7, dtype=bool)
    ok[4] = False  # invalid: zero code
    fused = encode_tensors(rows, ok, dictionary, lam, gram=gram, backend="numba")
    z, flat = normalise_rows(rows)
    assert flat.tolist() == [False, False, True, False, False, True, False]
    two_steps = encode_rows(z, dictionary, lam, skip=flat | ~ok, gram=gram, backend="numba")
    assert np.allclose(fused, two_steps, rtol=0, atol=1e-12)
    assert np.all(fused[[2, 4, 5]] == 0.0)
    assert np.count_nonzero(fused[[0, 1, 3, 6]], axis=1).min() > 0
    reference = encode_tensors(rows, ok, dictionary, lam, gram=gram, backend="sklearn")
    assert np.abs(fused - reference).max() < 1e-5


@needs_numba
def test_numba_encoder_edge_cases() -> None:
    rng = np.random.default_rng(14)
    dictionary = random_dictionary(30, 20, rng)
    dictionary[7] = 0.0  # a dead atom (dictionary learning can leave one): never used
    lam = sparsity_penalty(20)
    z, _ = normalise_rows(rng.standard_normal((5, 20)))
    codes = encode_rows(z, dictionary, lam, backend="numba")
    assert np.isfinite(codes).all() and np.all(codes[:, 7] == 0.0)
    # A penalty above every correlation gives the zero code (the first gap test ends it).
    assert np.all(encode_rows(z, dictionary, 10.0, backend="numba") == 0.0)
    # The atom itself is coded by that atom alone, shrunk by λ (unit atoms).
    atom = dictionary[3] - dictionary[3].mean()
    atom /= np.linalg.norm(atom)
    single = encode_rows(atom[np.newaxis], np.vstack([atom, np.eye(20)[:1] * 0]), 0.1)
    assert single[0].tolist() == pytest.approx([0.9, 0.0])
    # Too few sweeps: a warning, not a silent wrong code.
    with pytest.warns(RuntimeWarning, match="did not converge"):
        encode_rows(z, random_dictionary(30, 20, rng), lam, max_iter=1, backend="numba")
    with pytest.raises(ValueError, match="backend"):
        encode_rows(z, dictionary, lam, backend="cuda")


@needs_numba
def test_numba_encoder_converges_on_near_duplicate_atoms() -> None:
    # A dictionary fitted briefly on few rows can hold near-copies of an atom (the
    # sfrnn wiring test's electrodes dictionary did). Coordinate descent then creeps along
    # the pair for thousands of sweeps; scikit-learn's sparse_encode stops unconverged on
    # 10 of these 30 rows. Ours steps by solving on the support and must reach the optimum.
    from sklearn.decomposition import sparse_encode

    rng = np.random.default_rng(15)
    dictionary = random_dictionary(16, 95, rng)
    for atom, copy in ((4, 5), (8, 9)):
        near = dictionary[atom] + 1e-3 * rng.standard_normal(95)
        dictionary[copy] = near / np.linalg.norm(near)
    lam = sparsity_penalty(95)
    weights = np.zeros((30, 16))
    weights[:, [2, 4, 5, 8, 9]] = rng.uniform(0.3, 1.0, (30, 5)) * rng.choice([-1, 1], (30, 5))
    z, _ = normalise_rows(weights @ dictionary + 0.05 * rng.standard_normal((30, 95)))
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no "did not converge"
        ours = encode_rows(z, dictionary, lam, backend="numba")
    correlation = (z - ours @ dictionary) @ dictionary.T
    support = ours != 0
    assert np.abs(correlation[support] - lam * np.sign(ours[support])).max() < 1e-9
    assert np.abs(correlation[~support]).max() <= lam + 1e-9
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        theirs = sparse_encode(z, dictionary, algorithm="lasso_cd", alpha=lam)
    objective_ours = _objective(z, ours, dictionary, lam)
    assert np.all(objective_ours <= _objective(z, theirs, dictionary, lam) + 1e-12)
