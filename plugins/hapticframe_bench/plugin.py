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
    """Yield the suites: ``search``, ``search-scenes``, ``search-physics``, ``search-devices``,
    ``search-dynamixel``, ``fuzz``, ``perception``, ``perception-real``,
    ``biotac-calibration``, ``bhm``, ``latency`` and
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
        name="search-physics",
        summary="Table 3.2 in the mpm-sand world (Newton MPM response library): today's "
        "defaults, models calibrated there, Table 3.1's parameters, beside the sandbox.",
        factory="hapticframe_bench._search_physics:run_search_physics",
        install_hint="pip install hapticframe[plots]  (search.png needs matplotlib)",
    )
    yield BenchSpec(
        name="search-distance",
        summary="Haptic search, Table 3.2's protocol: the failure-zone kernel beside the "
        "distance estimate (sandbox force as 4 real taxels, raking-estimator trained on "
        "sandbox approaches, distance-estimate sensor model).",
        factory="hapticframe_bench._search_distance:run_search_distance",
        install_hint="pip install torch  (the raking estimator trains with it)",
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
        name="perception-real",
        summary="Contact detection on real BioTac trials (Penn BOLT, --data DIR) against a "
        "reference derived from pdc, with and without pdc: models trained on synthetic, "
        "calibrated synthetic and other objects' real trials, and the linear SVM baselines.",
        factory="hapticframe_bench._perception_real:run_perception_real",
        install_hint="pip install 'hapticframe[learn,hdf5]'",
    )
    yield BenchSpec(
        name="biotac-calibration",
        summary="Calibrate the synthetic BioTac on real recordings (--data DIR of Penn BOLT "
        "files): writes the generator's parameters and a figure of real, uncalibrated and "
        "calibrated statistics.",
        factory="hapticframe_bench._biotac_calibration:run_biotac_calibration",
        install_hint="pip install 'hapticframe[hdf5,plots]'",
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
        name="raking-real",
        summary="Real raking data (Chen et al., IROS 2024): our raking-estimator against the "
        "authors' trained LSTMs on their 20 test trials, per input set.",
        factory="hapticframe_bench._raking_real:run_raking_real",
        install_hint="pip install 'hapticframe[learn,tables]'  (torch trains ours; h5py reads "
        "theirs)",
    )
    yield BenchSpec(
        name="raking-real-cv",
        summary="How raking-real's settings were chosen: grouped cross-validation on the 80 "
        "real training trials only, per input set (distance cap, steps left out, window).",
        factory="hapticframe_bench._raking_real_cv:run_raking_real_cv",
        install_hint=_LEARN_HINT,
    )
    yield BenchSpec(
        name="raking-jamming",
        summary="The force/force-rate jamming rule on real raking data: calibrated on 80 "
        "trials, first-flag distance and far false alarms on 20, force against distance.",
        factory="hapticframe_bench._raking_jamming:run_raking_jamming",
        install_hint="pip install 'hapticframe[plots]'  (the figure)",
    )
    yield BenchSpec(
        name="jamming-detection",
        summary="Jamming detection relative to the movement's own drag beside the absolute "
        "force/force-rate rule: per-sample ROC and the distance at the first flag at 1 false "
        "alarm per metre, in the sandbox, mpm-sand and the real raking trials.",
        factory="hapticframe_bench._jamming_detection:run_jamming_detection",
        install_hint="pip install 'hapticframe[plots]'  (the figure)",
    )
    yield BenchSpec(
        name="raking-map",
        summary="Where the 20 real raking test trials place the object: the distance-estimate "
        "sensor model against the fixed distance of the failure zone's rule.",
        factory="hapticframe_bench._raking_map:run_raking_map",
        install_hint="pip install 'hapticframe[plots]'  (the figure)",
    )
    yield BenchSpec(
        name="emd-fidelity",
        summary="EMD sifting stop and cap against fidelity (IMF 1-3 agreement with a "
        "converged reference, orthogonality), time per frame and downstream accuracy; "
        "220,000 samples against PyEMD.",
        factory="hapticframe_bench._emd_fidelity:run_emd_fidelity",
        install_hint="pip install 'hapticframe[learn]' EMD-signal  (PyEMD for the cross-check)",
    )
