"""The shared Butterworth low-pass filter (hapticframe.filters) against scipy, its reference."""

from __future__ import annotations

import numpy as np
import pytest

from hapticframe.filters import butterworth_sos, sos_filter, sos_step_state


@pytest.mark.parametrize("order", [1, 2, 3, 4])
@pytest.mark.parametrize(("cutoff", "rate"), [(3.0, 100.0), (0.5, 100.0), (20.0, 50.0)])
def test_butterworth_matches_scipy(order, cutoff, rate):
    from scipy import signal

    ours = butterworth_sos(cutoff, rate, order)
    theirs = signal.butter(order, cutoff, btype="low", output="sos", fs=rate)
    assert ours.shape == theirs.shape
    impulse = np.zeros(400)
    impulse[0] = 1.0
    np.testing.assert_allclose(
        signal.sosfilt(ours, impulse), signal.sosfilt(theirs, impulse), rtol=0, atol=1e-12
    )
    np.testing.assert_allclose(
        sos_step_state(ours), signal.sosfilt_zi(ours), rtol=1e-10, atol=1e-12
    )


def test_filter_state_holds_a_constant_and_both_paths_agree():
    sos = butterworth_sos(3.0, 100.0, 4)
    out, state = sos_filter(sos, np.full(50, 2.5), sos_step_state(sos) * 2.5)
    np.testing.assert_allclose(out, 2.5, rtol=1e-12)
    np.testing.assert_allclose(state, sos_step_state(sos) * 2.5, rtol=1e-12)
    rng = np.random.default_rng(2)
    x = rng.standard_normal(600)  # longer than the plain-float path takes
    long_out, long_state = sos_filter(sos, x, np.zeros((2, 2)))
    short_out, short_state = sos_filter(sos, x[:200], np.zeros((2, 2)))
    rest_out, rest_state = sos_filter(sos, x[200:400], short_state)
    last_out, last_state = sos_filter(sos, x[400:], rest_state)
    np.testing.assert_allclose(np.concatenate([short_out, rest_out, last_out]), long_out,
                               rtol=0, atol=1e-12)
    np.testing.assert_allclose(last_state, long_state, rtol=0, atol=1e-12)
    with pytest.raises(ValueError, match="order"):
        butterworth_sos(3.0, 100.0, 0)


def test_the_frequency_response_equals_scipys_to_rounding():
    from scipy import signal

    for order in (1, 2, 3, 4, 6):
        for cutoff, rate in ((3.0, 100.0), (10.0, 1000.0), (0.5, 100.0), (24.0, 50.0)):
            ours = butterworth_sos(cutoff, rate, order)
            theirs = signal.butter(order, cutoff, output="sos", fs=rate)
            _, h_ours = signal.sosfreqz(ours, worN=512, fs=rate)
            _, h_theirs = signal.sosfreqz(theirs, worN=512, fs=rate)
            np.testing.assert_allclose(np.abs(h_ours), np.abs(h_theirs), rtol=0, atol=1e-12)


@pytest.mark.parametrize(("cutoff", "rate"), [(0.0, 100.0), (50.0, 100.0), (np.nan, 100.0)])
def test_a_cutoff_outside_zero_to_nyquist_is_refused(cutoff, rate):
    with pytest.raises(ValueError, match="Nyquist"):
        butterworth_sos(cutoff, rate, 2)
