"""Registration of the benchmark suites (import-light: no runner imports).

``hapticframe bench`` with no name lists them, one line each; ``hapticframe bench NAME``
runs one.
"""

from __future__ import annotations

from collections.abc import Iterator

from hapticframe import BenchSpec, hookimpl

__all__ = ["hapticframe_benchmarks"]

_LEARN_HINT = "pip install 'hapticframe[learn]'"


@hookimpl
def hapticframe_benchmarks() -> Iterator[BenchSpec]:
    """Yield the suites: ``search``, ``search-scenes``, ``search-devices``,
    ``search-dynamixel``, ``fuzz``, ``perception``, ``bhm``, ``latency`` and
    ``emd-fidelity``."""
    yield BenchSpec(
        name="search",
        summary="Haptic search, Table 3.2: two-phase planner (bundled defaults and Table "
        "3.1's parameters) vs coverage baseline, circle and ellipse at random placements.",
        factory="hapticframe_bench._search:run_search",
        install_hint="pip install hapticframe[plots]  (search.png needs matplotlib)",
    )
    yield BenchSpec(
        name="search-scenes",
        summary="Haptic search beyond Table 3.2: an L-shape, a 5-point star, and "
        "two and three objects at once, every object scored.",
        factory="hapticframe_bench._search:run_search_scenes",
        install_hint="pip install hapticframe[plots]  (search.png needs matplotlib)",
    )
    yield BenchSpec(
        name="search-devices",
        summary="Haptic search through emulated FT 300 + BNO055 and the force observer "
        "beside the pure simulation: accuracy, per-step cost, calibration, health.",
        factory="hapticframe_bench._search_devices:run_search_devices",
        install_hint="pip install 'hapticframe[hardware]'  (pyserial for the emulated ports)",
    )
    yield BenchSpec(
        name="search-dynamixel",
        summary="Haptic search on a whole emulated rig: a Dynamixel gantry, FT 300, BNO055 "
        "and the force observer, the sandbox following the gantry.",
        factory="hapticframe_bench._search_dynamixel:run_search_dynamixel",
        install_hint="pip install 'hapticframe[hardware]'  (dynamixel-sdk, pyserial)",
    )
    yield BenchSpec(
        name="fuzz",
        summary="Mutants of the examples, damaged recordings and bags, concurrent writers, "
        "fault schedules and a hostile live-page client: each refused with a located "
        "message or run to a clean end; --trials cases per family (default 320 mutants, "
        "100 of each other family).",
        factory="hapticframe_bench._fuzz:run_fuzz",
    )
    yield BenchSpec(
        name="perception",
        summary="Dissertation Tables 2.2, 2.3, 2.4 and A.1 on the synthetic BioTac dataset, "
        "plus the streaming chain's latency per frame.",
        factory="hapticframe_bench._perception:run_perception",
        install_hint=_LEARN_HINT,
    )
    yield BenchSpec(
        name="bhm",
        summary="Bayesian Hilbert Map: fit 3,000 points, add 200, mean and std on 15,000.",
        factory="hapticframe_bench._bhm:run_bhm_bench",
    )
    yield BenchSpec(
        name="latency",
        summary="Streaming BioTac chain per 10 ms frame: emd-features, sparse-coding and an "
        "sf-rnn step, one thread; our EMD against PyEMD.",
        factory="hapticframe_bench._latency:run_latency_bench",
        install_hint=_LEARN_HINT,
    )
    yield BenchSpec(
        name="emd-fidelity",
        summary="EMD sifting stop and cap against fidelity (IMF 1-3 agreement with a "
        "converged reference, orthogonality), time per frame and downstream accuracy; "
        "220,000 samples against PyEMD.",
        factory="hapticframe_bench._emd_fidelity:run_emd_fidelity",
        install_hint="pip install 'hapticframe[learn]' EMD-signal  (PyEMD for the cross-check)",
    )
