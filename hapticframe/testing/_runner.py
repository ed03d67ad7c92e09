"""Running the checks: imperatively (``hapticframe check``) or as pytest parameters."""

from __future__ import annotations

from collections.abc import Callable, Iterable, Iterator, Mapping
from dataclasses import dataclass
from typing import Any

from hapticframe._registry import Registry
from hapticframe._specs import PluginSpec
from hapticframe.testing._common import CHECKS, CheckFunction
from hapticframe.testing._harness import CheckFailure

__all__ = ["CheckResult", "checks_for", "iter_checks", "parametrize_with_checks", "run_checks"]

ExpectedFailures = Mapping[str, str] | Callable[[PluginSpec], Mapping[str, str]] | None


@dataclass(frozen=True)
class CheckResult:
    """The outcome of one check: PASS, FAIL, XFAIL (declared and failed) or XPASS."""

    check: str
    status: str
    message: str = ""


def checks_for(spec: PluginSpec) -> list[CheckFunction]:
    """The check functions that apply to ``spec``'s kind, in order."""
    return list(CHECKS[spec.kind])


def _expected(spec: PluginSpec, expected: ExpectedFailures) -> Mapping[str, str]:
    if expected is None:
        return {}
    return expected(spec) if callable(expected) else expected


def iter_checks(
    spec: PluginSpec,
    *,
    registry: Registry | None = None,
    expected_failed_checks: ExpectedFailures = None,
) -> Iterator[CheckResult]:
    """Run every applicable check on ``spec``, yielding each result as it finishes (never
    raises); :func:`run_checks` collects them. Parameters as for :func:`run_checks`."""
    expected = _expected(spec, expected_failed_checks)
    for func in checks_for(spec):
        name = func.__name__
        try:
            func(spec, registry=registry)
        except CheckFailure as exc:
            yield CheckResult(name, "XFAIL" if name in expected else "FAIL", str(exc))
            continue
        except Exception as exc:  # a crash inside a check is the plugin's failure too
            yield CheckResult(name, "XFAIL" if name in expected else "FAIL",
                              f"{type(exc).__name__}: {exc}")
            continue
        if name in expected:
            yield CheckResult(name, "XPASS", f"expected to fail: {expected[name]}")
        else:
            yield CheckResult(name, "PASS")


def run_checks(
    spec: PluginSpec,
    *,
    registry: Registry | None = None,
    expected_failed_checks: ExpectedFailures = None,
) -> list[CheckResult]:
    """Run every applicable check on ``spec`` and collect the results (never raises).

    Parameters
    ----------
    spec : PluginSpec
    registry : Registry, optional
        Where ``spec.check_inputs`` are looked up (default: the installed plugins).
    expected_failed_checks : mapping or callable, optional
        ``{check_name: reason}`` (or a function of the spec returning one): these checks
        are reported as XFAIL when they fail, and as XPASS (a failure) when they pass.
    """
    return list(iter_checks(spec, registry=registry,
                            expected_failed_checks=expected_failed_checks))


def parametrize_with_checks(
    specs: Iterable[PluginSpec],
    *,
    expected_failed_checks: ExpectedFailures = None,
) -> Any:
    """A ``pytest.mark.parametrize`` over (spec, check) pairs, one test id per check.

    Use it as::

        @parametrize_with_checks(my_specs)
        def test_conformance(spec, check):
            check(spec)

    Ids read ``sensor/biotac::check_sensor_contract``, so ``pytest -k`` selects checks.
    Declared expected failures become strict ``xfail`` marks.
    """
    import pytest

    params = []
    for spec in specs:
        expected = _expected(spec, expected_failed_checks)
        for func in checks_for(spec):
            marks: tuple[pytest.MarkDecorator, ...] = ()
            if func.__name__ in expected:
                marks = (pytest.mark.xfail(strict=True, reason=expected[func.__name__]),)
            params.append(pytest.param(
                spec, func, id=f"{spec.kind.value}/{spec.name}::{func.__name__}", marks=marks
            ))
    return pytest.mark.parametrize(("spec", "check"), params)
