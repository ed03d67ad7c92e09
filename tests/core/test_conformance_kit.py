"""The conformance kit accepts correct plugins and rejects each broken one helpfully."""

from __future__ import annotations

import pytest

from hapticframe.testing import CHECKS, parametrize_with_checks, run_checks
from tests.support.broken import BROKEN, GOOD


@pytest.mark.parametrize("spec", GOOD, ids=lambda s: f"{s.kind.value}/{s.name}")
def test_correct_plugins_pass_every_check(spec):
    failed = [r for r in run_checks(spec) if r.status != "PASS"]
    assert not failed, failed


@pytest.mark.parametrize("spec, check, fragment", BROKEN, ids=[b[0].name for b in BROKEN])
def test_broken_plugins_are_rejected_with_a_helpful_message(spec, check, fragment):
    results = {r.check: r for r in run_checks(spec)}
    assert results[check].status == "FAIL", results[check]
    assert fragment in results[check].message, results[check].message


def test_every_check_can_fail():
    covered = {check for _, check, _ in BROKEN}
    every = {func.__name__ for funcs in CHECKS.values() for func in funcs}
    assert every <= covered, f"no broken plugin exercises {sorted(every - covered)}"


def test_declared_expected_failures_are_xfail_and_xpass_is_reported():
    spec, check, _ = BROKEN[4]
    results = {r.check: r.status for r in run_checks(spec, expected_failed_checks={check: "known"})}
    assert results[check] == "XFAIL"
    good = GOOD[0]
    results = {
        r.check: r.status for r in run_checks(good, expected_failed_checks={"check_builds": "?"})}
    assert results["check_builds"] == "XPASS"


@parametrize_with_checks([GOOD[0], BROKEN[4][0]], expected_failed_checks=lambda spec: (
    {"check_sensor_contract": "its clock restarts", "check_deterministic": "its clock restarts",
     "check_sensor_keeps_time": "its clock restarts",
     "check_sensor_read_all_matches_reads": "it ends, and its reads restart the clock"}
    if spec.name == "restarting-clock" else {}))
def test_parametrize_with_checks_gives_one_test_per_check(spec, check):
    check(spec)


def test_the_package_docstring_lists_every_check():
    import hapticframe.testing

    every = {func.__name__ for funcs in CHECKS.values() for func in funcs}
    missing = sorted(name for name in every if f"``{name}``" not in hapticframe.testing.__doc__)
    assert not missing, f"hapticframe.testing's docstring does not list {missing}"


def test_the_import_probe_answers_as_a_fresh_interpreter_would():
    from hapticframe.testing import _import_probe as probe

    modules = ("hapticframe_coverage.plugin", "hapticframe_coverage._config")
    fresh = probe._fresh_interpreter(modules)
    helper = probe._shared_probe()
    assert helper is not None and "numpy" in helper.base
    assert not fresh - probe._probed(helper, modules)  # nothing a fresh start loads is missed
    # Asked of the helper (not in its base), and of a fresh interpreter (in its base).
    assert "xml.dom.minicompat" not in helper.base and "decimal" in helper.base
    assert probe.modules_loaded_by(["xml.dom.minidom"], ["xml.dom.minicompat", "torch"]) == {
        "xml.dom.minicompat"}
    assert probe.modules_loaded_by(["json"], ["xml.dom.minicompat"]) == set()
    assert probe.modules_loaded_by(["tests.support.heavy_config"], ["decimal"]) == {"decimal"}
    with pytest.raises(ImportError, match="no_such_module_for_the_kit"):
        probe.modules_loaded_by(["no_such_module_for_the_kit"], ["torch"])
