"""The contact reference derived from pdc, the calibration from real recordings and the
calibrated press generator."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from hapticframe_biotac import (
    BioTacCalibration,
    BioTacFrames,
    PdcReference,
    calibrate_biotac,
    derived_from_pdc,
    generate_press_trial,
    layout_for,
)
from hapticframe_biotac._calibration import pac_band_power
from tests.support.bolt_fixture import press_finger


def test_reference_rises_above_rest_with_hysteresis() -> None:
    pdc = np.full(300, 800.0)
    pdc[150:200] = 825.0  # above on (20)
    pdc[200:220] = 815.0  # between off (10) and on: stays contact
    pdc[220:230] = 805.0  # below off: free
    pdc[230:240] = 815.0  # between: does not start contact again
    labels = derived_from_pdc(pdc, rest_frames=100, on_counts=20, off_counts=10)
    np.testing.assert_array_equal(np.flatnonzero(labels), np.arange(150, 220))
    # The resting level is the mean of the first frames, not zero.
    assert derived_from_pdc(pdc + 1000.0).sum() == 70
    assert PdcReference(50, 5.0, 2.0)(pdc).sum() == 90  # 150-240 (815 > 2 above rest)
    assert PdcReference().as_dict()["name"] == "derived from pdc"
    with pytest.raises(ValueError, match="off_counts <= on_counts"):
        derived_from_pdc(pdc, on_counts=5, off_counts=10)
    with pytest.raises(ValueError, match="frame 3 is not finite"):
        derived_from_pdc(np.r_[pdc[:3], np.nan, pdc[4:]])
    with pytest.raises(ValueError, match="resting frames"):
        derived_from_pdc(pdc[:50])
    assert derived_from_pdc(np.full(100, 7.0)).sum() == 0  # constant: never contact


def _frames(rng: np.random.Generator, n: int = 1500, drift: float = 0.0) -> BioTacFrames:
    f = press_finger(rng, n, (400, 1100), depth=150.0)
    t = np.arange(n) * 0.01
    return BioTacFrames(layout_for("biotac"), t, f["pac"], f["pdc"] + drift * t, f["tac"],
                        f["tdc"], f["electrodes"])


def test_calibration_recovers_what_it_measures() -> None:
    rng = np.random.default_rng(1)
    recordings = [_frames(rng) for _ in range(4)]
    cal = calibrate_biotac(recordings)
    # press_finger: pdc rests near 1800 with noise 1.5; a 150-count press for 7 s.
    assert cal.rest_pdc == pytest.approx(1800, abs=1.0)
    assert cal.noise_pdc == pytest.approx(1.5, rel=0.25)
    assert cal.noise_pac == pytest.approx(2.0, rel=0.25)
    peaks = [e["peak"] for rec in cal.episodes for e in rec]
    assert len(peaks) == 4 and all(145 < p < 160 for p in peaks)
    durations = [e["duration_s"] for rec in cal.episodes for e in rec]
    assert all(6.5 < d < 7.1 for d in durations)
    # Electrodes fall by 150 × U(0.2, 1) per unit load: gains between -1 and -0.2.
    gains = np.asarray(cal.electrode_gain)
    assert gains.shape == (2, 19) and np.all(gains < -0.15) and np.all(gains > -1.05)
    # The band powers add up to the resting pac noise (white, 2 counts).
    bands = pac_band_power(np.random.default_rng(2).normal(0.0, 2.0, 22_000))
    assert np.sqrt(np.sum(bands**2)) == pytest.approx(2.0 * np.sqrt(1087.5 / 1100), rel=0.1)
    with pytest.raises(ValueError, match="no recording has a contact"):
        calibrate_biotac([r.select(slice(0, 300)) for r in recordings])
    with pytest.raises(ValueError, match="at least one recording"):
        calibrate_biotac([])
    drifting = calibrate_biotac([_frames(rng, 3000, drift=d) for d in (-0.4, 0.4)])
    assert drifting.drift_pdc_per_s == pytest.approx(0.4, rel=0.2)


def test_calibration_round_trips_and_drives_the_generator(tmp_path: Path) -> None:
    rng = np.random.default_rng(3)
    cal = calibrate_biotac([_frames(rng) for _ in range(4)])
    back = BioTacCalibration.load(cal.save(tmp_path / "cal.json"))
    assert back == cal
    a = generate_press_trial(back, np.random.default_rng(5))
    b = generate_press_trial(back, np.random.default_rng(5))
    np.testing.assert_array_equal(a.electrodes, b.electrodes)
    # The generated trials measure like the real ones.
    again = calibrate_biotac([generate_press_trial(cal, np.random.default_rng(s), finger=s % 2)
                              for s in range(6)])
    assert again.rest_pdc == pytest.approx(cal.rest_pdc, abs=3 * cal.rest_pdc_spread + 2)
    assert again.noise_pdc == pytest.approx(cal.noise_pdc, rel=0.3)
    assert np.median([e["peak"] for r in again.episodes for e in r]) == pytest.approx(
        np.median([e["peak"] for r in cal.episodes for e in r]), rel=0.25)
    np.testing.assert_allclose(np.asarray(again.electrode_gain),
                               np.asarray(cal.electrode_gain), atol=0.15)
    labels = derived_from_pdc(a.pdc)
    assert 0.2 < labels.mean() < 0.8 and labels[:100].sum() == 0
    with pytest.raises(ValueError, match="finger 2"):
        generate_press_trial(cal, rng, finger=2)
    with pytest.raises(ValueError, match="more than 110 frames"):
        generate_press_trial(cal, rng, n_frames=50)
    (tmp_path / "bad.json").write_text('{"format": "other"}')
    with pytest.raises(ValueError, match=r"bad\.json: not a BioTac calibration"):
        BioTacCalibration.load(tmp_path / "bad.json")
