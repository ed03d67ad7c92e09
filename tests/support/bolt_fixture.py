"""Small recordings in the Penn BOLT HDF5 layout: rest in air, press, hold, release.

The real BOLT files have no stated licence and stay outside the repository; these stand in
for them in tests (same layout, raw 12-bit counts, whole-second stamps).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np


def press_finger(rng: np.random.Generator, n: int, press: tuple[int, int],
                 depth: float = 120.0) -> dict[str, np.ndarray]:
    """One fingertip's channels: resting counts plus a press between frames ``press``."""
    load = np.zeros(n)
    a, b = press
    ramp = min(20, max(1, (b - a) // 4))
    load[a:b] = 1.0
    load[a:a + ramp] = np.linspace(0.0, 1.0, ramp)
    load[b - ramp:b] = np.linspace(1.0, 0.0, ramp)
    pdc = 1800 + depth * load + rng.normal(0, 1.5, n)
    electrodes = (3000 + rng.normal(0, 200, 19)[None, :]
                  - 150 * load[:, None] * rng.uniform(0.2, 1.0, 19)[None, :]
                  + rng.normal(0, 1.5, (n, 19)))
    pac = 2040 + rng.normal(0, 2.0, (n, 22))
    onset = np.diff(load, prepend=0.0)
    pac += 300 * onset[:, None] * np.sin(np.linspace(0, 6 * np.pi, 22))[None, :]
    return {"pac": np.rint(pac), "pdc": np.rint(pdc), "tac": np.rint(2050 + rng.normal(0, 1, n)),
            "tdc": np.rint(2500 + rng.normal(0, 1, n)), "electrodes": np.rint(electrodes)}


def bolt_trials(rng: np.random.Generator, name: str, count: int = 2, n: int = 600,
                start_s: int = 1_342_570_000) -> dict[str, Any]:
    """``count`` trials named ``<name>_NN``: 100 frames per whole second (60 in the first)."""
    out = {}
    for k in range(count):
        stamps = start_s + 1000 * k + (np.arange(n) + 40) // 100
        press = (max(int(n * 0.3), 120), int(n * 0.8))  # after 100 resting frames
        out[f"{name}_{k + 1:02d}"] = (stamps, [press_finger(rng, n, press),
                                               press_finger(rng, n, press, depth=90.0)])
    return out


def write_bolt_dir(directory: Path, objects: tuple[str, ...] = ("cork", "metal_bar"),
                   count: int = 2, n: int = 600, seed: int = 0) -> Path:
    """One BOLT file per object in ``directory``."""
    from hapticframe_biotac import save_bolt

    rng = np.random.default_rng(seed)
    directory.mkdir(parents=True, exist_ok=True)
    for name in objects:
        save_bolt(directory / f"{name}.h5", bolt_trials(rng, name, count, n))
    return directory
