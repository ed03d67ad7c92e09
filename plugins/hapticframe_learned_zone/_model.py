"""The learned-zone sensor model: a report's likelihood over the cells around the plate.

Where the failure-zone kernel assumes the dissertation's mechanics (a rupture distance
from the soil's angles, a sector ahead of the plate), this model reads off calibration
recordings how often the classifier reported each class while each cell of a grid fixed to
the plate held the known object, and while it did not (:mod:`._functional`). A report then
says, for each cell, log LR = log p(report | occupied) − log p(report | free); the map gets
the target sigmoid(log LR) (the posterior from an even prior) with a weight that grows with
the ratio's size and falls with its uncertainty, and cells whose ratio is near 0 get
nothing. A jamming report in sand whose rise starts 2.5 cm ahead thus speaks about the cells
2.5 cm ahead, and a free report clears only as far ahead as free reports really ruled the
object out — in whatever sand it was calibrated.

Reports are placed as the failure-zone kernel places them: the first sample of a movement,
one every ``observation_spacing_m`` of travel, and every change of the reported class; the
travel and the last class are carried across calls, so rows observed one at a time give the
observations of the rows observed at once.
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping, Sequence
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from hapticframe import atomic_write
from hapticframe.kinds import (
    BuildContext,
    CalibrationRecording,
    LocatedMeasurement,
    MovementResult,
    Observations,
    SensorModel,
)

from ._config import LearnedZoneConfig
from ._functional import (
    cell_offsets,
    count_reports,
    depth_band,
    inside_outlines,
    likelihood_tables,
    log_ratio,
    observation_weights,
    onset_window,
    place,
    survival_background,
    travel_thinning,
)

__all__ = ["ARTIFACT", "FORMAT", "LearnedZone", "fit_counts"]

FloatArray = NDArray[np.float64]

#: The file :meth:`LearnedZone.save` writes, and its format tag.
ARTIFACT = "learned_zone.json"
FORMAT = "hapticframe-learned-zone/1"
#: The model shipped with the plugin (learned in the analytic sandbox; data/SOURCE.md).
BUNDLED = "sandbox.json"
_NOTHING = Observations.empty()
_CHUNK = 512  # samples per block while counting: (block, cells) booleans stay small


class LearnedZone(SensorModel):
    """Sensor model learned from calibration recordings (see the module docstring).

    Parameters
    ----------
    config : LearnedZoneConfig
    context : BuildContext
    """

    def __init__(self, config: LearnedZoneConfig, context: BuildContext) -> None:
        super().__init__(config, context)
        self._report: dict[str, Any] = {}
        self._fitted = False
        if config.model_dir is not None:
            self.load(config.model_dir)
        else:
            text = resources.files(__package__).joinpath("data").joinpath(BUNDLED).read_text()
            self._use(_parse(json.loads(text), f"the bundled {BUNDLED}"))
        self.reset()

    # --- state ----------------------------------------------------------------------------------

    def reset(self) -> None:
        """Forget the travel bookkeeping."""
        self._last_xy: tuple[float, float] | None = None
        self._travel_m = 0.0
        self._last_class = -1

    def on_movement_end(self, result: MovementResult) -> None:
        """The next movement starts its own travel count."""
        self.reset()

    # --- the model ------------------------------------------------------------------------------

    def _use(self, model: dict[str, Any]) -> None:
        """Take a parsed model (counts and grid) and derive its likelihood tables."""
        self.classes: tuple[str, ...] = tuple(model["classes"])
        self.ahead_m = np.asarray(model["ahead_m"], dtype=np.float64)
        self.aside_m = np.asarray(model["aside_m"], dtype=np.float64)
        self.depth_edges_m = np.asarray(model["depth_edges_m"], dtype=np.float64)
        self.offsets_m = cell_offsets(self.ahead_m, self.aside_m)
        self._counts = (np.asarray(model["counts_occupied"], dtype=np.float64),
                        np.asarray(model["counts_free"], dtype=np.float64))
        self.class_marginal = np.asarray(model["class_marginal"], dtype=np.float64)
        self.p_occupied, self.p_free, self.occupied_samples = likelihood_tables(
            *self._counts, self.class_marginal, self.config.prior_strength,
            self.config.depth_prior_strength)
        self._model = model
        self._columns: dict[tuple[str, ...], NDArray[np.intp]] = {}
        self._survival: tuple[FloatArray, FloatArray] | None = None
        if self.config.background_likelihood == "survival":
            self._survival = survival_background(
                self._counts[0].sum(axis=0), self.p_free[-1][:, 0], self.class_marginal[0],
                self.config.prior_strength, (self.ahead_m.size, self.aside_m.size))

    def cell_maps(self, probabilities: Sequence[float], depth_m: float = math.nan
                  ) -> tuple[FloatArray, FloatArray, FloatArray]:
        """For one report (class probabilities in the model's class order) at ``depth_m``
        (NaN: pooled over depths), per cell (``ahead × aside``): the map's target σ(log LR),
        the log likelihood ratio and the weight. With ``background_likelihood: survival`` a
        report of the background class alone takes its ratio from
        :func:`~._functional.survival_background` (at every depth)."""
        band = int(depth_band([depth_m], self.depth_edges_m)[0])
        row = len(self.depth_edges_m) + 1 if band < 0 else band
        q = np.asarray(probabilities, dtype=np.float64)
        q = q / q.sum() if q.sum() > 0 else np.full(q.size, 1.0 / q.size)
        if self._survival is not None and q[0] == 1.0:
            # The background's survival estimate (depths pooled) and its samples.
            ratio, samples = (a.copy() for a in self._survival)
        else:
            ratio = log_ratio(self.p_occupied[row], self.p_free[row], q)
            # A sparse band's likelihoods are mostly the pooled ones (it is shrunk towards
            # them), so their evidence is the samples pooled over depths.
            samples = self.occupied_samples[-1]
        weights = observation_weights(ratio, samples, self.config.prior_strength,
                                      self.config.full_weight_log_ratio)
        # The target is the posterior from an even prior, σ(log LR): the map fits soft
        # labels (it averages targets, it does not add log odds), and the calibration
        # scenes' base rate (an object always near) is not the search's.
        targets = 1.0 / (1.0 + np.exp(-np.clip(ratio, -700.0, 700.0)))
        shape = (self.ahead_m.size, self.aside_m.size)
        return targets.reshape(shape), ratio.reshape(shape), weights.reshape(shape)

    def _columns_of(self, classes: tuple[str, ...]) -> NDArray[np.intp]:
        """Column of each model class in a measurement's classes (cached per tuple)."""
        cached = self._columns.get(classes)
        if cached is None:
            missing = [c for c in self.classes if c not in classes]
            extra = [c for c in classes if c not in self.classes]
            if missing or extra:
                raise ValueError(
                    f"learned zone {self.id!r}: the classifier reports {list(classes)}, the "
                    f"model was learned on {list(self.classes)}; fit it on recordings of "
                    "this classifier")
            cached = np.array([classes.index(c) for c in self.classes], dtype=np.intp)
            self._columns[classes] = cached
        return cached

    # --- observations ---------------------------------------------------------------------------

    def observe(self, measurement: LocatedMeasurement) -> Observations:
        """Cells and targets of the reports of ``measurement`` placed on the map."""
        n = len(measurement)
        if n == 0:
            return Observations.empty()
        columns = self._columns_of(tuple(measurement.classes))
        probabilities = _reports(measurement.probabilities[:, columns], self.config.mixture)
        positions = measurement.positions_m
        headings = measurement.headings_rad
        if not (np.isfinite(positions).all() and np.isfinite(headings).all()):
            raise ValueError(f"learned zone {self.id!r}: positions and headings must be finite")
        emit = self._emitted(positions.tolist(), np.argmax(probabilities, axis=1).tolist())
        if not emit:
            return _NOTHING
        cfg = self.config
        parts = []
        for i in emit:
            targets, ratio, weights = (a.ravel() for a in self.cell_maps(
                probabilities[i], float(measurement.depth_m[i])))
            keep = (np.abs(ratio) >= cfg.min_log_ratio) & (weights > 0)
            if not keep.any():
                continue
            points = place(self.offsets_m[keep], positions[i], headings[i])[0]
            parts.append(Observations(points, targets[keep], weights[keep]))
        if not parts:
            return _NOTHING
        return parts[0] if len(parts) == 1 else Observations.concatenate(parts)

    def _emitted(self, positions: list[list[float]], states: list[int]) -> list[int]:
        """Rows that place a report; updates the travel state carried across calls."""
        spacing = self.config.observation_spacing_m
        rows = []
        for i, ((x, y), state) in enumerate(zip(positions, states, strict=True)):
            if self._last_xy is None:
                emit = True
            else:
                before = self._travel_m
                self._travel_m += math.hypot(x - self._last_xy[0], y - self._last_xy[1])
                emit = (state != self._last_class or spacing <= 0
                        or math.floor(self._travel_m / spacing) > math.floor(before / spacing))
            if emit:
                rows.append(i)
            self._last_xy = (x, y)
            self._last_class = state
        return rows

    # --- training (hapticframe train, run.calibration_runs) --------------------------------------

    def fit(self, recordings: Sequence[CalibrationRecording]) -> None:
        """Count, per cell and depth band, each class reported with the cell occupied and
        free, over every calibration recording.

        Raises
        ------
        ValueError
            With no recordings, recordings of different classes, or when no counted sample
            had the object in the grid (the movements never came near it).
        """
        model, report = fit_counts(recordings, self.config)
        self._use(_parse(model, "the fit"))
        self._fitted = True
        self._report = {**report, "reach_ahead_m": self.reach_ahead_m()}
        self._model["report"] = self._report
        self.reset()

    def reach_ahead_m(self) -> dict[str, float]:
        """Per class other than the first: the farthest cell straight ahead (aside 0, depths
        pooled) where reporting it raises the odds of occupancy above ×2 — how far ahead
        the calibration says that class speaks."""
        out: dict[str, float] = {}
        centre = int(np.argmin(np.abs(self.aside_m)))
        for k, name in enumerate(self.classes[1:], start=1):
            _, ratio, _ = self.cell_maps(np.eye(len(self.classes))[k])
            ahead = self.ahead_m[ratio[:, centre] > math.log(2.0)]
            out[name] = float(ahead.max()) if ahead.size else float("nan")
        return out

    def training_report(self) -> Mapping[str, Any]:
        """What the last fit counted (empty before a fit)."""
        return dict(self._report)

    def save(self, directory: str | Path) -> Path:
        """Write the counts and grid into ``directory/learned_zone.json`` (plain JSON).

        Raises
        ------
        ValueError
            Before any fit.
        """
        if not self._fitted:
            raise ValueError(f"learned zone {self.id!r}: nothing to save before a fit")
        target = Path(directory) / ARTIFACT
        atomic_write(target, json.dumps(self._model, indent=1) + "\n")
        return target

    def load(self, directory: str | Path) -> None:
        """Read the model :meth:`save` wrote into ``directory``."""
        path = Path(directory) / ARTIFACT
        try:
            data = json.loads(path.read_text())
        except (OSError, ValueError) as exc:
            raise ValueError(f"{path}: not a learned-zone model "
                             f"({type(exc).__name__}: {exc})") from exc
        self._use(_parse(data, str(path)))
        self._report = dict(self._model.get("report") or {})
        self._fitted = True
        self.reset()

    def describe(self) -> dict[str, Any]:
        """The grid and classes, for run metadata."""
        return {"classes": list(self.classes), "cells": len(self.offsets_m),
                "depth_edges_m": self.depth_edges_m.tolist()}


def fit_counts(recordings: Sequence[CalibrationRecording], config: LearnedZoneConfig
               ) -> tuple[dict[str, Any], dict[str, Any]]:
    """The model (counts and grid, as :meth:`LearnedZone.save` writes it) and a report of
    what was counted, from calibration recordings (see :meth:`LearnedZone.fit`)."""
    cfg = config
    if not recordings:
        raise ValueError("no calibration recordings given")
    classes = recordings[0].classes
    for rec in recordings[1:]:
        if rec.classes != classes:
            raise ValueError(f"{rec.source}: classes {list(rec.classes)} differ from "
                             f"{recordings[0].source}'s {list(classes)}")
    ahead = np.arange(cfg.ahead_min_m, cfg.ahead_max_m + 1e-9, cfg.cell_m)
    aside = np.arange(-cfg.aside_max_m, cfg.aside_max_m + 1e-9, cfg.cell_m)
    offsets = cell_offsets(ahead, aside)
    edges = np.asarray(cfg.depth_edges_m, dtype=np.float64)
    bands = edges.size + 1
    n_occ = np.zeros((bands, len(offsets), len(classes)))
    n_free = np.zeros_like(n_occ)
    class_total = np.zeros(len(classes))
    counted, near, per_band = 0, 0, np.zeros(bands, dtype=np.int64)
    for rec in recordings:
        keep = travel_thinning(rec.positions_m, rec.movement_index, cfg.fit_spacing_m)
        keep &= onset_window(rec.positions_m, rec.movement_index, rec.labels(),
                             cfg.onset_travel_m)
        rows = np.flatnonzero(keep)
        reports = _reports(rec.probabilities, cfg.mixture)
        class_total += reports[rows].sum(axis=0)
        for start in range(0, rows.size, _CHUNK):
            block = rows[start:start + _CHUNK]
            occupied = inside_outlines(
                place(offsets, rec.positions_m[block], rec.headings_rad[block]),
                rec.outlines_m)
            band = depth_band(rec.depth_m[block], edges)
            o, f = count_reports(occupied, reports[block], band, bands)
            n_occ += o
            n_free += f
            counted += block.size
            near += int(occupied.any(axis=1).sum())
            per_band += np.bincount(band[band >= 0], minlength=bands)
    if near == 0:
        raise ValueError("no counted sample had the known object within the grid: record "
                         "movements that pass or meet it")
    model = {
        "format": FORMAT, "classes": list(classes), "ahead_m": ahead.tolist(),
        "aside_m": aside.tolist(), "depth_edges_m": edges.tolist(),
        "counts_occupied": n_occ.tolist(), "counts_free": n_free.tolist(),
        # Laplace-smoothed: a class never reported keeps a positive frequency.
        "class_marginal": ((class_total + 1.0) / (class_total.sum() + len(classes))).tolist(),
    }
    report = {
        "recordings": [rec.source for rec in recordings],
        "samples": int(sum(len(r) for r in recordings)),
        "samples_counted": counted,
        "samples_with_object_in_grid": near,
        "samples_per_depth_band": per_band.tolist(),
        "depth_edges_m": edges.tolist(),
        "classes": list(classes),
        "class_marginal": model["class_marginal"],
        "cells": len(offsets),
    }
    return model, report


def _reports(probabilities: FloatArray, mixture: str) -> FloatArray:
    """The reports as counted and observed: one-hot rows of the most probable class, or
    the probabilities themselves (``mixture: soft``)."""
    if mixture == "soft":
        return probabilities
    hard: FloatArray = np.eye(probabilities.shape[1])[np.argmax(probabilities, axis=1)]
    return hard


def _parse(data: Any, where: str) -> dict[str, Any]:
    """``data`` checked to be a learned-zone model whose arrays agree in shape."""
    if not isinstance(data, dict) or data.get("format") != FORMAT:
        raise ValueError(f"{where}: not a learned-zone model (format must be {FORMAT!r})")
    try:
        classes = [str(c) for c in data["classes"]]
        ahead = np.asarray(data["ahead_m"], dtype=np.float64)
        aside = np.asarray(data["aside_m"], dtype=np.float64)
        edges = np.asarray(data["depth_edges_m"], dtype=np.float64).reshape(-1)
        occ = np.asarray(data["counts_occupied"], dtype=np.float64)
        free = np.asarray(data["counts_free"], dtype=np.float64)
        marginal = np.asarray(data["class_marginal"], dtype=np.float64)
    except (KeyError, TypeError, ValueError) as exc:
        raise ValueError(f"{where}: a learned-zone model needs classes, ahead_m, aside_m, "
                         f"depth_edges_m, counts_occupied, counts_free and class_marginal "
                         f"({type(exc).__name__}: {exc})") from exc
    shape = (edges.size + 1, ahead.size * aside.size, len(classes))
    problems = []
    if not classes or ahead.ndim != 1 or aside.ndim != 1 or not ahead.size or not aside.size:
        problems.append("classes, ahead_m and aside_m must be non-empty lists")
    if occ.shape != shape or free.shape != shape:
        problems.append(f"counts must have shape {shape} (bands, cells, classes), got "
                        f"{occ.shape} and {free.shape}")
    if marginal.shape != (len(classes),):
        problems.append(f"class_marginal must hold {len(classes)} values")
    arrays = (ahead, aside, edges, occ, free, marginal)
    if not problems and not all(np.isfinite(a).all() for a in arrays):
        problems.append("values must be finite")
    if not problems and (occ.min() < 0 or free.min() < 0 or marginal.min() <= 0):
        problems.append("counts must be non-negative and class_marginal positive")
    if problems:
        raise ValueError(f"{where}: {'; '.join(problems)}")
    return {**data, "classes": classes}
