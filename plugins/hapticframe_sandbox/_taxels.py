"""The ``sandbox-taxels`` sensor: a declared measurement model from the sandbox's force to
the 4-taxel 3-axis normalized channels of a real raking tool (Chen, Versace & Jamone 2024).

The sandbox computes one 2-D force on the plate. A real tactile rake reads twelve channels
(4 taxels x, y, z), normalized to 0..1. The model, per taxel ``k`` and axis ``a``::

    taxel[k, a] = offset[k, a] + gain_along[k, a] * f_along + gain_across[k, a] * f_across
                  + noise_std[k, a] * N(0, 1)

with ``f_along`` the force resisting the motion (N, along the heading) and ``f_across`` the
force to the left of it (N). Its numbers are fitted from the real training trials by
:func:`fit_taxel_model` (``hapticframe_raking.calibrate_sandbox_taxels`` runs it against
sandbox approaches); the defaults of :class:`SandboxTaxelSensorConfig` are that fit
(``docs/benchmarks.md``, "Search with the distance estimate").

Every sample also carries the truth the raking estimator trains on: ``distance_mm`` from the
fingertip to the nearest object outline, ``direction_class`` (0: the nearest point lies more
than ``direction_split_deg`` clockwise of the heading, 2: as far counter-clockwise, 1:
between) and ``depth_class`` (0: raking at least ``deep_m`` deep, 1: shallower).

With ``approach_trials > 0`` the sensor is a finite source for ``hapticframe train``: it
drives its robot through that many straight approaches at the scene's objects (each a
recording) and is exhausted after them.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Iterator, Mapping
from dataclasses import dataclass
from types import MappingProxyType
from typing import Any

import numpy as np
from numpy.typing import NDArray

from hapticframe.kinds import BuildContext, ChannelInfo, MovementResult, SampleBatch, Sensor

from ._config import SandboxTaxelSensorConfig
from ._robot import SandboxRobot
from ._scenarios import approach_movement

__all__ = ["TaxelModel", "SandboxTaxelSensor", "fit_taxel_model", "force_components",
           "raking_labels"]

TAXEL_CHANNEL = "taxel_force"
_OUTLINE_POINTS = 256


@dataclass(frozen=True)
class TaxelModel:
    """The declared measurement model's numbers, each ``(4, 3)`` (taxel, axis)."""

    offset: NDArray[np.float64]
    gain_along_per_n: NDArray[np.float64]
    gain_across_per_n: NDArray[np.float64]
    noise_std: NDArray[np.float64]

    @classmethod
    def from_config(cls, config: SandboxTaxelSensorConfig) -> TaxelModel:
        def grid(values: tuple[float, ...]) -> NDArray[np.float64]:
            return np.asarray(values, dtype=np.float64).reshape(4, 3)

        return cls(grid(config.offset), grid(config.gain_along_per_n),
                   grid(config.gain_across_per_n), grid(config.noise_std))

    def apply(self, f_along_n: NDArray[np.float64], f_across_n: NDArray[np.float64],
              rng: np.random.Generator) -> NDArray[np.float64]:
        """``(n, 4, 3)`` taxel readings of forces ``(n,)``, with the model's noise."""
        a = np.asarray(f_along_n, dtype=np.float64)[:, None, None]
        c = np.asarray(f_across_n, dtype=np.float64)[:, None, None]
        mean = self.offset + self.gain_along_per_n * a + self.gain_across_per_n * c
        out: NDArray[np.float64] = mean + self.noise_std * rng.standard_normal(mean.shape)
        return out


def force_components(forces_n: NDArray[np.float64], heading_rad: NDArray[np.float64]
                     ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """``(f_along, f_across)``: the force against the motion and to its left (N)."""
    h = np.asarray(heading_rad, dtype=np.float64)
    f = np.asarray(forces_n, dtype=np.float64).reshape(-1, 2)
    along = -(f[:, 0] * np.cos(h) + f[:, 1] * np.sin(h))
    across = -f[:, 0] * np.sin(h) + f[:, 1] * np.cos(h)
    return along, across


def raking_labels(positions_m: NDArray[np.float64], heading_rad: NDArray[np.float64],
                  depth_m: NDArray[np.float64], outlines: list[NDArray[np.float64]],
                  *, direction_split_deg: float, deep_m: float
                  ) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """Per sample: distance (mm) to the nearest outline point, direction and depth class.

    With no object the distance is NaN and the direction class 1 (ahead)."""
    p = np.asarray(positions_m, dtype=np.float64).reshape(-1, 2)
    n = len(p)
    depth_class = (np.asarray(depth_m, dtype=np.float64) < deep_m).astype(np.float64)
    if not outlines or n == 0:
        return np.full(n, np.nan), np.ones(n), depth_class
    points = np.concatenate(outlines)
    gaps = points[None, :, :] - p[:, None, :]
    dist = np.hypot(gaps[..., 0], gaps[..., 1])
    nearest = np.argmin(dist, axis=1)
    rows = np.arange(n)
    delta = gaps[rows, nearest]
    bearing = np.degrees(np.arctan2(delta[:, 1], delta[:, 0]) - heading_rad)
    bearing = (bearing + 180.0) % 360.0 - 180.0
    direction = np.where(bearing < -direction_split_deg, 0.0,
                         np.where(bearing > direction_split_deg, 2.0, 1.0))
    return 1000.0 * dist[rows, nearest], direction, depth_class


def fit_taxel_model(real_force: NDArray[np.float64], real_distance_mm: NDArray[np.float64],
                    real_direction: NDArray[np.int64], sandbox_along_n: NDArray[np.float64],
                    sandbox_across_n: NDArray[np.float64],
                    sandbox_distance_mm: NDArray[np.float64],
                    sandbox_direction: NDArray[np.int64],
                    bin_edges_mm: tuple[float, ...] = (0, 15, 25, 35, 50, 70, 100, 150, 1e9),
                    min_count: int = 20,
                    noise_floor: NDArray[np.float64] | None = None) -> TaxelModel:
    """Fit the measurement model: scale from matched means, noise from what is left.

    Real and sandbox samples are grouped in the same cells (distance band x direction
    class). Each channel's real cell means are regressed (least squares, cells weighted
    by the square root of the smaller count) on the sandbox cell means of ``f_along`` and
    ``f_across`` plus a constant: offset and the two gains. The noise is what the real
    data varies within a cell beyond what the scaled sandbox force varies there
    (per-channel, pooled over cells), at least ``noise_floor`` (12 numbers; e.g. the real
    sample-to-sample noise) and 1e-3.
    """
    rf = np.asarray(real_force, dtype=np.float64).reshape(-1, 12)
    rd = np.asarray(real_distance_mm, dtype=np.float64)
    sd = np.asarray(sandbox_distance_mm, dtype=np.float64)
    sa = np.asarray(sandbox_along_n, dtype=np.float64)
    sc = np.asarray(sandbox_across_n, dtype=np.float64)
    if not (len(rf) == len(rd) == len(real_direction)) or not (
            len(sa) == len(sc) == len(sd) == len(sandbox_direction)):
        raise ValueError("fit_taxel_model: the arrays of one source differ in length")
    if not np.all(np.isfinite(rf)) or not np.all(np.isfinite(rd)):
        raise ValueError("fit_taxel_model: the real samples are not all finite")
    ok = np.isfinite(sd) & np.isfinite(sa) & np.isfinite(sc)
    sd, sa, sc = sd[ok], sa[ok], sc[ok]
    sdir = np.asarray(sandbox_direction)[ok]
    rows, targets, weights, within_real, within_sim = [], [], [], [], []
    for lo, hi in itertools.pairwise(bin_edges_mm):
        for k in range(3):
            r = (rd >= lo) & (rd < hi) & (np.asarray(real_direction) == k)
            s = (sd >= lo) & (sd < hi) & (sdir == k)
            if r.sum() < min_count or s.sum() < min_count:
                continue
            rows.append([1.0, sa[s].mean(), sc[s].mean()])
            targets.append(rf[r].mean(axis=0))
            weights.append(math.sqrt(min(r.sum(), s.sum())))
            within_real.append((r.sum(), rf[r].var(axis=0)))
            within_sim.append((s.sum(), sa[s].var(), sc[s].var()))
    if len(rows) < 4:
        raise ValueError(f"fit_taxel_model: only {len(rows)} cells hold {min_count} samples "
                         "of both sources; at least 4 are needed")
    w = np.asarray(weights)[:, None]
    coef, *_ = np.linalg.lstsq(np.asarray(rows) * w, np.asarray(targets) * w, rcond=None)
    total_r = sum(n for n, _ in within_real)
    var_real = sum(n * v for n, v in within_real) / total_r
    total_s = sum(n for n, _, _ in within_sim)
    var_along = sum(n * v for n, v, _ in within_sim) / total_s
    var_across = sum(n * v for n, _, v in within_sim) / total_s
    explained = coef[1] ** 2 * var_along + coef[2] ** 2 * var_across
    noise = np.sqrt(np.maximum(var_real - explained, 1e-6))
    if noise_floor is not None:
        noise = np.maximum(noise, np.asarray(noise_floor, dtype=np.float64).reshape(12))
    return TaxelModel(coef[0].reshape(4, 3), coef[1].reshape(4, 3), coef[2].reshape(4, 3),
                      noise.reshape(4, 3))


class SandboxTaxelSensor(Sensor):
    """The sandbox plate's force as a real rake's 12 taxel channels (module docstring).

    Parameters
    ----------
    config : SandboxTaxelSensorConfig
    context : BuildContext
        ``inputs``: one sandbox robot.
    """

    def __init__(self, config: SandboxTaxelSensorConfig, context: BuildContext) -> None:
        super().__init__(config, context)
        robots = [r for r in context.inputs.values() if isinstance(r, SandboxRobot)]
        if len(robots) != 1 or len(context.inputs) != 1:
            raise ValueError(f"sensor {context.id!r} (type 'sandbox-taxels') needs one "
                             "input, a robot of type 'sandbox'")
        self._robot = robots[0]
        scene = self._robot.scene
        self._objects = list(scene.objects)
        self._outlines = [np.asarray(o.outline(_OUTLINE_POINTS), dtype=np.float64)
                          for o in self._objects]
        self._model = TaxelModel.from_config(config)
        self._rng = context.rng
        self._cursor = self._robot.steps_taken
        self._trials_done = 0
        rate = self._robot.control_rate_hz
        self._channels = MappingProxyType({
            TAXEL_CHANNEL: ChannelInfo(shape=(4, 3), unit="1", rate_hz=rate),
            "distance_mm": ChannelInfo(shape=(), unit="mm", rate_hz=rate),
            "direction_class": ChannelInfo(shape=(), unit="1", rate_hz=rate),
            "depth_class": ChannelInfo(shape=(), unit="1", rate_hz=rate),
        })

    @property
    def channels(self) -> Mapping[str, ChannelInfo]:
        return self._channels

    @property
    def model(self) -> TaxelModel:
        return self._model

    def read(self) -> SampleBatch:
        """The robot's steps since the previous read, as taxel readings with their truth."""
        if self.config.approach_trials:
            raise RuntimeError(f"sensor {self.id!r}: with approach_trials it is a training "
                               "source (hapticframe train), not a live sensor")
        return self._since_cursor()

    def _since_cursor(self) -> SampleBatch:
        truth = self._robot.ground_truth
        first = self._cursor
        self._cursor = len(truth)
        t = truth.timestamps_s[first:]
        if t.size == 0:
            return SampleBatch.empty(self._channels)
        positions = truth.positions_m[first:]
        heading = np.full(t.size, self._robot.state.heading_rad)
        along, across = force_components(truth.forces_n[first:], heading)
        distance, direction, depth = raking_labels(
            positions, heading, truth.depth_m[first:], self._outlines,
            direction_split_deg=self.config.direction_split_deg, deep_m=self.config.deep_m)
        return SampleBatch(t, {TAXEL_CHANNEL: self._model.apply(along, across, self._rng),
                               "distance_mm": distance, "direction_class": direction,
                               "depth_class": depth})

    @property
    def exhausted(self) -> bool:
        return bool(self.config.approach_trials) and (
            self._trials_done >= self.config.approach_trials)

    def iter_recordings(self) -> Iterator[SampleBatch]:
        """One approach per recording, round the scene's objects (training source)."""
        if not self.config.approach_trials:
            yield from super().iter_recordings()
            return
        if not self._objects:
            raise ValueError(f"sensor {self.id!r}: approach_trials needs objects in the scene")
        while not self.exhausted:
            k = self._trials_done
            movement = approach_movement(self._rng, self._objects[k % len(self._objects)],
                                         standoff_m=self.config.approach_standoff_m)
            self._robot.begin(movement)
            self._cursor = self._robot.steps_taken
            while self._robot.step() is not None:
                pass
            batch = self._since_cursor()
            self._robot.on_movement_end(MovementResult(
                index=k, movement=movement, halted=bool(self._robot.halt_reason),
                halt_reason=self._robot.halt_reason, final_state=self._robot.state))
            self._trials_done += 1
            if len(batch):
                yield batch

    def checkpoint(self) -> tuple[int, Mapping[str, Any]]:
        """The read cursor and the noise generator's state (a closed loop's lookahead)."""
        return self._cursor, self._rng.bit_generator.state

    def rewind(self, checkpoint: tuple[int, Mapping[str, Any]]) -> None:
        self._cursor, generator = checkpoint
        self._rng.bit_generator.state = generator

    def reset(self) -> None:
        self._cursor = self._robot.steps_taken
