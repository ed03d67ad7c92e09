"""The conformance kit: checks every plugin of a kind must pass.

Run it on your own plugins, in pytest::

    from hapticframe.testing import parametrize_with_checks
    from my_lab_plugin.plugin import SPECS

    @parametrize_with_checks(SPECS)
    def test_conformance(spec, check):
        check(spec)

or without pytest: ``hapticframe check my-sensor``. Checks cover the interface contract
(shapes, dtypes, units, increasing timestamps), determinism under a fixed seed, streaming
and batch agreeing, the config's JSON Schema round trip, lazy importing, and numerical
extremes (zero, constant, huge, tiny and NaN input give finite output or a clear error).

What each kind is held to, beyond the checks every plugin gets (``check_spec_record``,
``check_config_round_trip``, ``check_lazy_import``, ``check_builds``, ``check_knobs``
(each declared knob names a config field and its values validate),
``check_declared_sizes`` (each field the validator declares with a ``hapticframe.Size`` is
refused at the extremes of its range, or built and driven there within the memory limit),
``check_run_range_ends`` (each end of an acceleration's, a depth's or a filter cutoff's
range is refused or driven cleanly, without an error or NaN, and no thread count above the
machine's CPUs is accepted),
``check_deterministic``):

- sensors: ``check_sensor_contract`` (declared channels, float64, strictly increasing
  times; every sensor is read until it ends, bounded by reads and by seconds of its own
  clock, and one that ends without declaring ``finite`` is told to declare it),
  ``check_sensor_keeps_time`` (driven for 100 control periods of the run's clock, its time
  advances by 100 periods within one sample; the message gives the fix),
  ``check_sensor_valid_samples_finite`` (no NaN or
  infinity in a sample the batch marks valid), ``check_sensor_read_all_matches_reads``
  (the ``read_all()`` and joined ``iter_recordings()`` of a sensor that ends equal what
  successive ``read()`` calls deliver), ``check_rewind``;
- feature extractors and classifiers: ``check_stream_contract``,
  ``check_streaming_matches_batch``, ``check_aligned_inputs_stream_as_batch`` (a consumer
  whose ``input_alignment`` is ``hold`` or ``linear`` gets two inputs on different clocks,
  joined tick by tick as a run joins them, and must give the batch result),
  ``check_numerical_extremes``, ``check_rewind``;
- sensor models: ``check_sensor_model_contract``, ``check_sensor_model_streaming``,
  ``check_sensor_model_extremes``;
- maps: ``check_map_contract``, ``check_map_streaming_matches_batch``,
  ``check_map_extremes``, ``check_map_ranks_scattered_points``,
  ``check_map_refuses_bad_query_points``;
- planners: ``check_planner_contract``, ``check_planner_extremes`` (an all-unknown map, an
  all-occupied map, a region smaller than one line spacing);
- robots: ``check_robot_contract``, ``check_robot_halt``, ``check_robot_stops_at_once``
  (after ``halt()``, before the first step or mid-movement, no step returns a state and
  the fingertip stays put), ``check_robot_refuses_outside_workspace`` (a robot that declares
  a ``workspace`` raises ``ValueError`` from ``begin()`` for a movement leaving it),
  ``check_robot_refuses_bad_depth`` (zero, negative, NaN), ``check_robot_extremes`` (a
  zero-length movement, movements that leave the workspace),
  ``check_rewind``.

A :class:`~hapticframe.kinds.Device` the kit builds is configured and activated first,
and deactivated and cleaned up when a check is done with it (``release_component``).

Every loop the kit drives is bounded (reads, steps, ``max_movements``), so a plugin that
never ends fails a check instead of hanging it; no check is timed.
"""

# _knobs first: its spec-level check runs beside the other checks every plugin gets.
from hapticframe.testing import (  # noqa: F401  (registers the kind checks)
    _knobs,
    _rewind,
    _sizes,
    _spatial,
    _streams,
)
from hapticframe.testing._common import (
    CHECKS,
    HEAVY_MODULES,
    check_builds,
    check_config_round_trip,
    check_lazy_import,
    check_spec_record,
)
from hapticframe.testing._harness import (
    DEFAULT_SCENE,
    CheckFailure,
    KitMap,
    make_component,
    release_component,
    synthetic_batch,
)
from hapticframe.testing._knobs import check_knobs
from hapticframe.testing._rewind import check_rewind
from hapticframe.testing._runner import (
    CheckResult,
    checks_for,
    iter_checks,
    parametrize_with_checks,
    run_checks,
)
from hapticframe.testing._sizes import check_declared_sizes, check_run_range_ends
from hapticframe.testing._spatial import (
    check_deterministic,
    check_map_contract,
    check_map_extremes,
    check_map_ranks_scattered_points,
    check_map_refuses_bad_query_points,
    check_map_streaming_matches_batch,
    check_planner_contract,
    check_planner_extremes,
    check_robot_contract,
    check_robot_extremes,
    check_robot_halt,
    check_robot_refuses_bad_depth,
    check_robot_refuses_outside_workspace,
    check_robot_stops_at_once,
    check_sensor_model_contract,
    check_sensor_model_extremes,
    check_sensor_model_streaming,
    located_measurement,
    map_observations,
    planner_episode,
)
from hapticframe.testing._streams import (
    check_aligned_inputs_stream_as_batch,
    check_numerical_extremes,
    check_sensor_contract,
    check_sensor_keeps_time,
    check_sensor_read_all_matches_reads,
    check_sensor_valid_samples_finite,
    check_stream_contract,
    check_streaming_matches_batch,
    drive_sensor,
)

__all__ = [
    "CHECKS",
    "CheckFailure",
    "CheckResult",
    "DEFAULT_SCENE",
    "HEAVY_MODULES",
    "KitMap",
    "check_aligned_inputs_stream_as_batch",
    "check_builds",
    "check_config_round_trip",
    "check_declared_sizes",
    "check_deterministic",
    "check_knobs",
    "check_lazy_import",
    "check_map_contract",
    "check_map_extremes",
    "check_map_ranks_scattered_points",
    "check_map_refuses_bad_query_points",
    "check_map_streaming_matches_batch",
    "check_numerical_extremes",
    "check_planner_contract",
    "check_planner_extremes",
    "check_rewind",
    "check_robot_contract",
    "check_robot_extremes",
    "check_robot_halt",
    "check_robot_refuses_bad_depth",
    "check_robot_refuses_outside_workspace",
    "check_robot_stops_at_once",
    "check_run_range_ends",
    "check_sensor_contract",
    "check_sensor_keeps_time",
    "check_sensor_model_contract",
    "check_sensor_model_extremes",
    "check_sensor_model_streaming",
    "check_sensor_read_all_matches_reads",
    "check_sensor_valid_samples_finite",
    "check_spec_record",
    "check_stream_contract",
    "check_streaming_matches_batch",
    "checks_for",
    "drive_sensor",
    "iter_checks",
    "located_measurement",
    "make_component",
    "map_observations",
    "parametrize_with_checks",
    "planner_episode",
    "release_component",
    "run_checks",
    "synthetic_batch",
]
