"""The kit reads every sensor until it ends (issue 26 §8): a lab's sensor that ends without
declaring ``finite`` is not let off after a few reads."""

from __future__ import annotations

import numpy as np

from hapticframe import SensorSpec
from hapticframe.kinds import SampleBatch
from hapticframe.testing import run_checks
from tests.support.broken import UntaredReadAllSensor
from tests.support.labplugin import SweepConfig, SweepSensor

HERE = "tests.core.test_kit_reads_to_the_end"
#: One sample a read, 100 reads: the recording ends at read 100.
ONE_A_READ = {"samples": 100, "chunk": 1}


class LateNanSensor(SweepSensor):
    """Ends after 100 reads (without declaring ``finite``); read 60 delivers a NaN it
    calls valid."""

    def read(self) -> SampleBatch:
        index = self._next
        batch = super().read()
        if index != 60:
            return batch
        force = np.array(batch.channels["force_n"])
        force[:] = np.nan
        return SampleBatch(batch.timestamps_s, {**batch.channels, "force_n": force})


class EndingUntaredSensor(UntaredReadAllSensor):
    """Ends without declaring ``finite``; its read_all() disagrees with its reads."""


def _results(factory: str) -> dict[str, tuple[str, str]]:
    spec = SensorSpec(f"lab-{factory.lower()}", "a lab's sensor", SweepConfig,
                      f"{HERE}:{factory}", check_config=ONE_A_READ)
    return {r.check: (r.status, r.message) for r in run_checks(spec)}


def test_a_nan_at_read_60_of_an_undeclared_finite_sensor_is_found():
    results = _results("LateNanSensor")
    status, message = results["check_sensor_valid_samples_finite"]
    assert status == "FAIL" and "read 60 delivered NaN" in message, message


def test_a_disagreeing_read_all_of_an_undeclared_finite_sensor_is_found():
    results = _results("EndingUntaredSensor")
    status, message = results["check_sensor_read_all_matches_reads"]
    assert status == "FAIL" and "read_all() and successive read()s" in message, message
    assert "declare the 'finite' capability" in message


def test_the_author_is_told_to_declare_finite():
    status, message = _results("LateNanSensor")["check_sensor_contract"]
    assert status == "FAIL", message
    assert "ended (exhausted) after 100 reads" in message
    assert "does not declare the 'finite' capability" in message


def test_a_live_sensor_passes_and_a_declared_finite_one_is_still_read_to_its_end():
    live = SensorSpec("lab-live-sweep", "never ends within the kit's bound", SweepConfig,
                      "tests.support.labplugin:SweepSensor",
                      check_config={"samples": 5000, "chunk": 1})
    failed = [r for r in run_checks(live) if r.check.startswith("check_sensor")
              and r.status != "PASS"]
    assert not failed, failed
    finite = SensorSpec("lab-finite-sweep", "ends", SweepConfig,
                        "tests.support.labplugin:SweepSensor", capabilities=frozenset({"finite"}),
                        check_config=ONE_A_READ)
    failed = [r for r in run_checks(finite) if r.status != "PASS"]
    assert not failed, failed
