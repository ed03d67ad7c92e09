"""The ``belief-map`` map: RBF support-vector classification with Platt scaling (App. A.4).

The thesis stores fingertip contact estimates at their positions in an RBF SVC (Eq. A.9,
A.10) and calibrates its scores into ``P(object | x)`` with Platt scaling (Eq. A.11),
refitting every 10 classifier steps. Here:

- The classifier is an ``SVC(kernel="rbf")`` fitted on all points, and Platt's sigmoid
  ``P = sigmoid(s f + c)`` fitted on held-out decision values ``f`` (what
  ``CalibratedClassifierCV(method="sigmoid", ensemble=False)`` does, and ``SVC(probability=
  True)``, deprecated in scikit-learn 1.9). Two differences keep the map from inverting
  (issue 16: 3,000 noisy scattered points, 6.4 cm cells, AUC 0.04): the held-out data are
  raw observations (dealt to folds by a hash of their position and binned per fold), not
  bins, whose free and contact twins in one coarse cell would score each other; and the
  slope is bounded, ``s >= 0``, so a higher decision value never lowers ``P``
  (:func:`._functional.calibration_splits`, :func:`._functional.platt_fit`).
- Labels are the contact decision (target > 0.5), as the thesis labels with the SF-RNN's
  state; observation weights become sample weights.
- The update cost is bounded: observations are binned per (cell, decided class) into a
  summed weight and a mean position (:mod:`._functional`), and the cell size doubles
  whenever more than ``max_points`` bins exist. A refit therefore sees at most
  ``max_points`` weighted points, whatever the number of observations; a bin of ``k``
  coincident observations is exactly ``k`` duplicated points to the SVM.
- Until each class has bins in at least two cells (calibration needs two folds), the
  map returns the Laplace-smoothed contact fraction ``(w_contact + 1) / (w + 2)`` on observed
  ground (blended into the unexplored prior as below): 0.5 everywhere before any
  observation, never NaN.
- Far from every observation the probability returns to ``unexplored_prior`` (0.5, the
  uniform prior of App. A.4): ``mean = w p + (1 - w) prior`` with ``w`` the RBF kernel to the
  nearest observation bin (less the bin's half diagonal). The bare SVC would return
  ``sigmoid(A b + B)`` there, which
  follows the class balance of what was seen, not anything about the unexplored ground.
  ``unexplored_prior: null`` switches the blend off.
- ``query`` returns ``mean = P(object | x)`` and ``std = sqrt(p (1 - p))``: the spread of the
  Bernoulli variable "object here", not the posterior uncertainty of ``p`` itself (an SVC
  has none).

Snapshots for Fig. 2.7 are the fitted maps right after the refits that first include the
first contact, the middle contact and the last contact observation (contact decided from
the targets in arrival order). They are kept as fitted classifiers and evaluated on the
final region when the run finishes.
"""

from __future__ import annotations

import time
from collections import deque
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from hapticframe.kinds import BuildContext, Map, MapEstimate, Observations, Region, RunOutcome
from hapticframe.threads import blas_threads

from . import _functional as fn
from ._config import BeliefMapConfig

__all__ = ["BeliefMap", "BeliefSnapshot", "PlattSVC", "fit_calibrated_svc"]

FloatArray = NDArray[np.float64]

_THESIS_REGION = Region(0.0, 0.75, 0.0, 0.50)
#: Grid cells along the long side of a figure's map (a finer grid looks the same).
_FIGURE_CELLS = 120
#: Most fingertip positions kept for the figures' path; beyond it every other one is dropped.
_PATH_POINTS = 20_000


@dataclass(frozen=True)
class PlattSVC:
    """An RBF SVC and the monotone Platt link of its decision values.

    Attributes
    ----------
    svc : sklearn.svm.SVC
        Fitted on every point (classes 0 free, 1 contact).
    slope : float
        ``s >= 0`` in ``P(contact) = sigmoid(s f + c)``.
    intercept : float
        ``c``.
    """

    svc: Any
    slope: float
    intercept: float

    def link(self, decision: ArrayLike) -> FloatArray:
        """``sigmoid(slope * decision + intercept)``: non-decreasing in ``decision``."""
        from scipy.special import expit

        return np.asarray(
            expit(self.slope * np.asarray(decision, dtype=np.float64) + self.intercept),
            dtype=np.float64,
        )

    def probability(self, points_m: FloatArray) -> FloatArray:
        """``P(contact)`` at (centred) ``points_m``."""
        return self.link(self.svc.decision_function(points_m))


def fit_calibrated_svc(
    bins: fn.Bins,
    splits: list[tuple[fn.Bins, fn.Bins]],
    origin_m: FloatArray,
    *,
    gamma_per_m2: float,
    penalty_c: float,
    seed: int,
) -> PlattSVC:
    """Fit an RBF SVC on ``bins`` and Platt's monotone sigmoid on held-out decision values.

    Parameters
    ----------
    bins : Bins
        Training points (merged over folds), with both classes.
    splits : list of (Bins, Bins)
        ``(training, held-out)`` pairs (:func:`._functional.calibration_splits`); each
        training set holds both classes.
    origin_m : (2,) float64
        Subtracted from every position before fitting (the RBF is translation invariant;
        centring keeps libsvm's ``|x|^2 + |y|^2 - 2 x.y`` distances accurate far from the
        origin).
    """
    # scikit-learn loads only when a map is first fitted.
    from sklearn import config_context
    from sklearn.svm import SVC

    def svc(train: fn.Bins) -> Any:
        model = SVC(kernel="rbf", gamma=gamma_per_m2, C=penalty_c, random_state=seed)
        return model.fit(train.positions - origin_m, train.labels, sample_weight=train.weights)

    # The problems are tiny: BLAS threads only add start-up cost (Platt's 2-parameter fit
    # took 60 ms instead of 10 ms with OpenBLAS threads on two cores).
    # Inputs are finite by construction (Observations validates them); scikit-learn's
    # per-call parameter validation costs more than the small SVC fits themselves.
    with (
        blas_threads(1),
        config_context(assume_finite=True, skip_parameter_validation=True),
    ):
        decision = np.concatenate([
            svc(train).decision_function(held.positions - origin_m) for train, held in splits
        ])
        final = svc(bins)
        slope, intercept = fn.platt_fit(
            decision,
            np.concatenate([held.labels for _, held in splits]),
            np.concatenate([held.weights for _, held in splits]),
        )
    return PlattSVC(final, slope, intercept)


@dataclass(frozen=True)
class BeliefSnapshot:
    """A fitted map at one moment.

    Attributes
    ----------
    observations_seen : int
        Observations fused when it was fitted (it includes indices below this).
    model : PlattSVC
        The fitted classifier and link; never refitted in place.
    origin_m : (2,) float64
        Subtracted from query points before prediction.
    fingertip_m : (2,) float64
        Position of the latest observation at that moment.
    """

    observations_seen: int
    model: PlattSVC
    origin_m: FloatArray
    fingertip_m: FloatArray
    representatives_m: FloatArray
    cell_size_m: float
    length_scale_m: float
    unexplored_prior: float | None

    def probability(self, points_m: FloatArray) -> FloatArray:
        """``P(object | x)`` at ``points_m`` (finite, (q, 2))."""
        if points_m.shape[0] == 0:
            return np.empty(0)
        with blas_threads(1):
            p = np.clip(self.model.probability(points_m - self.origin_m), 0.0, 1.0)
        return _blend(
            p, points_m, self.representatives_m, self.cell_size_m, self.length_scale_m,
            self.unexplored_prior,
        )


def _blend(
    p: FloatArray,
    points_m: FloatArray,
    representatives_m: FloatArray,
    cell_size_m: float,
    length_scale_m: float,
    prior: float | None,
) -> FloatArray:
    if prior is None:
        return p
    w = fn.support_weight(points_m, representatives_m, length_scale_m, cell_size_m)
    return np.clip(w * p + (1.0 - w) * prior, 0.0, 1.0)


class BeliefMap(Map):
    """Belief map of Jia (2022), section 2.5 and Appendix A.4; see the module docstring."""

    config: BeliefMapConfig

    def __init__(self, config: BeliefMapConfig, context: BuildContext) -> None:
        super().__init__(config, context)
        # One seed for every refit: the folds of a refit depend only on its data.
        self._seed = int(context.rng.integers(0, 2**31 - 1))
        if config.region is not None:
            self._fixed_region: Region | None = config.region.to_region()
        elif context.scene is not None:
            self._fixed_region = context.scene.region.to_region()
        else:
            self._fixed_region = None
        self.refit_durations_s: deque[float] = deque(maxlen=10_000)
        self.reset()

    # --- state -------------------------------------------------------------------------------

    def reset(self) -> None:
        """Forget every observation, the fitted classifier and the snapshots."""
        self._bins = fn.Bins.empty()
        self._level = 0
        self._seen = 0
        self._pending = 0
        self._contact_weight = 0.0
        self._total_weight = 0.0
        self._lower: FloatArray | None = None
        self._upper: FloatArray | None = None
        self._latest_point = np.full(2, np.nan)
        # The fingertip's path for the figures: (arrival index, x, y) of every stride-th point.
        self._path = np.empty((0, 3))
        self._path_stride = 1
        self._current: BeliefSnapshot | None = None
        self._first_contact: int | None = None
        self._last_contact: int | None = None
        self._first_snapshot: BeliefSnapshot | None = None
        self._last_snapshot: BeliefSnapshot | None = None
        self._history: list[BeliefSnapshot] = []
        self.refits = 0

    @property
    def region(self) -> Region:
        """Config region, else the scene's, else the observed extent plus a margin."""
        if self._fixed_region is not None:
            return self._fixed_region
        if self._lower is None or self._upper is None:
            return _THESIS_REGION
        try:
            return Region(*fn.extent_region(self._lower, self._upper, self.config.region_margin_m))
        except ValueError:  # an extent near the float64 limit
            return _THESIS_REGION

    @property
    def cell_size_m(self) -> float:
        """The current bin edge: the configured size doubled once per coarsening."""
        return float(self.config.cell_size_m * 2.0**self._level)

    @property
    def representatives(self) -> int:
        """Number of (cell, class) bins the next refit is fitted on."""
        return self._bins.cells_and_classes

    @property
    def observations_seen(self) -> int:
        return self._seen

    @property
    def fitted(self) -> bool:
        """Whether an SVC is fitted (both classes seen in at least two cells each)."""
        return self._current is not None

    @property
    def contact_indices(self) -> tuple[int | None, int | None]:
        """Arrival index of the first and the last contact observation (None without contact)."""
        return self._first_contact, self._last_contact

    # --- updating ----------------------------------------------------------------------------

    def update(self, observations: Observations) -> None:
        """Bin the observations; refit once ``update_every`` have arrived since the last refit."""
        if not isinstance(observations, Observations):
            raise TypeError(f"update expects Observations, got {type(observations).__name__}")
        n = len(observations)
        if n == 0:
            return
        points, targets, weights = observations.points_m, observations.targets, observations.weights
        contact = np.flatnonzero(targets > 0.5)
        if contact.size:
            if self._first_contact is None:
                self._first_contact = self._seen + int(contact[0])
            self._last_contact = self._seen + int(contact[-1])
        low, high = points.min(axis=0), points.max(axis=0)
        self._lower = low if self._lower is None else np.minimum(self._lower, low)
        self._upper = high if self._upper is None else np.maximum(self._upper, high)
        self._latest_point = points[-1].copy()
        self._keep_path(points)
        self._total_weight += float(weights.sum())
        self._contact_weight += float(weights[targets > 0.5].sum())
        new_bins = fn.bin_observations(
            points, targets, weights, self.cell_size_m, self.config.calibration_folds
        )
        self._bins, self._level = fn.bound_bins(
            fn.merge_bins(self._bins, new_bins), self._level, self.config.max_points
        )
        self._seen += n
        self._pending += n
        if self._pending >= self.config.update_every:
            self.refit()

    def _keep_path(self, points: FloatArray) -> None:
        """Append the stride-th positions of this batch to the path, halving it when full."""
        index = self._seen + np.arange(len(points))
        keep = index % self._path_stride == 0
        self._path = np.vstack([self._path, np.column_stack([index[keep], points[keep]])])
        while len(self._path) > _PATH_POINTS:
            self._path_stride *= 2
            self._path = self._path[self._path[:, 0] % self._path_stride == 0]

    def fingertip_path(self, observations_seen: int | None = None) -> FloatArray:
        """``(n, 2)`` fingertip positions in arrival order (thinned on long runs), those
        before the ``observations_seen``-th observation when given."""
        rows = self._path
        if observations_seen is not None:
            rows = rows[rows[:, 0] < observations_seen]
        return rows[:, 1:3].copy()

    def refit(self) -> None:
        """Fit the classifier on the current bins now (a no-op for the prior's state)."""
        self._pending = 0
        merged = fn.merge_folds(self._bins)
        # A cell holds at most one merged bin per class: bins of a class count its cells.
        if np.bincount(merged.labels, minlength=2).min() < 2:
            self._current = None
            return
        started = time.perf_counter()
        splits = fn.calibration_splits(self._bins, self.config.calibration_folds, self._seed)
        positions = merged.positions
        weights = merged.weights
        origin = (weights[:, None] * positions).sum(axis=0) / weights.sum()
        model = fit_calibrated_svc(
            merged,
            splits,
            origin,
            gamma_per_m2=self.config.gamma_per_m2,
            penalty_c=self.config.penalty_c,
            seed=self._seed,
        )
        self.refit_durations_s.append(time.perf_counter() - started)
        self.refits += 1
        snapshot = BeliefSnapshot(
            self._seen, model, origin, self._latest_point.copy(), positions, self.cell_size_m,
            self.config.length_scale_m, self.config.unexplored_prior,
        )
        self._current = snapshot
        self._remember(snapshot)

    def _remember(self, snapshot: BeliefSnapshot) -> None:
        """Keep fitted maps from first contact on (first and last-contact ones exactly)."""
        if self._first_contact is None or self._last_contact is None:
            return
        if self._first_snapshot is None:
            self._first_snapshot = snapshot
        # A later contact observation makes the kept last-contact map stale.
        last = self._last_snapshot
        if last is None or last.observations_seen <= self._last_contact:
            self._last_snapshot = snapshot
        self._history.append(snapshot)
        if len(self._history) > self.config.max_snapshots:
            # Keep the first and the newest, thin the rest evenly.
            self._history = self._history[:-1:2] + [self._history[-1]]

    # --- queries -----------------------------------------------------------------------------

    def prior(self) -> float:
        """The mean on observed ground while no classifier is fitted: the smoothed contact share."""
        return fn.smoothed_fraction(self._contact_weight, self._total_weight)

    def _query(self, p: FloatArray) -> MapEstimate:
        """``P(object | x)`` and the Bernoulli spread ``sqrt(p (1 - p))`` at points ``p``."""
        if self._current is None:
            mean = _blend(
                np.full(len(p), self.prior()), p,
                self._bins.positions if len(self._bins) else np.empty((0, 2)),
                self.cell_size_m, self.config.length_scale_m, self.config.unexplored_prior,
            )
        else:
            mean = self._current.probability(p)
        return MapEstimate(mean, fn.bernoulli_std(mean))

    # --- snapshots and figures ---------------------------------------------------------------

    def snapshots(self) -> dict[str, BeliefSnapshot]:
        """Fitted maps at ``first_contact``, ``mid_contact`` and ``last_contact`` (those reached).

        Each is the map right after the first refit whose data include that observation
        (call :meth:`refit` first to include observations still waiting for the cadence).
        The middle one comes from a thinned history and may be a few refits late.
        """
        out: dict[str, BeliefSnapshot] = {}
        if self._first_contact is None or self._last_contact is None:
            return out
        if self._first_snapshot is not None:
            out["first_contact"] = self._first_snapshot
        middle = (self._first_contact + self._last_contact) // 2
        for snapshot in self._history:
            if snapshot.observations_seen > middle:
                out["mid_contact"] = snapshot
                break
        if (
            self._last_snapshot is not None
            and self._last_snapshot.observations_seen > self._last_contact
        ):
            out["last_contact"] = self._last_snapshot
        return out

    def snapshot_grid(
        self, snapshot: BeliefSnapshot | None = None, cells_long_side: int = 150
    ) -> tuple[FloatArray, FloatArray, FloatArray]:
        """``(xs, ys, mean)`` of ``snapshot`` (the current map when None) on a grid of
        ``cells_long_side`` cells along the long side of :attr:`region`; ``mean`` has shape
        ``(ny, nx)``.

        Not :meth:`~hapticframe.kinds.GridQueryable.probability_grid`: the belief map has no
        faster path than :meth:`query` on a grid, so it does not offer that protocol.
        """
        region = self.region
        width, height = region.size_m
        spacing = max(width, height) / cells_long_side
        xs, ys = region.grid(spacing)
        gx, gy = np.meshgrid(xs, ys)
        points = np.column_stack([gx.ravel(), gy.ravel()])
        if snapshot is None:
            mean = self.query(points).mean
        else:
            mean = snapshot.probability(points)
        return xs, ys, mean.reshape(len(ys), len(xs))

    def finalize(self, outcome: RunOutcome) -> Mapping[str, Any]:
        """Refit on waiting observations, write ``belief_<moment>.png`` and return counts."""
        if self._pending:
            self.refit()
        snapshots = self.snapshots()
        if outcome.figures:
            from ._plots import save_belief_figure

            out_dir = Path(outcome.out_dir)
            outlines = [] if outcome.scene is None else [o.outline() for o in outcome.scene.objects]
            # "Contact" here is the decided contact: an observation with P(contact) > 0.5.
            titles = {
                "first_contact": "(a) first decided contact",
                "mid_contact": "(b) middle decided contact",
                "last_contact": "(c) last decided contact",
            }
            for moment, snapshot in snapshots.items():
                xs, ys, mean = self.snapshot_grid(snapshot, _FIGURE_CELLS)
                save_belief_figure(
                    out_dir / f"belief_{moment}.png", xs, ys, mean,
                    title=f"Belief map at {titles[moment]}",
                    path_m=self.fingertip_path(snapshot.observations_seen), outlines=outlines,
                    outline_level=outcome.outline_level,
                )
            xs, ys, mean = self.snapshot_grid(None, _FIGURE_CELLS)
            save_belief_figure(
                out_dir / "belief_final.png", xs, ys, mean,
                title="Belief map at the end of the run",
                path_m=self.fingertip_path(), outlines=outlines,
                outline_level=outcome.outline_level,
            )
        return {
            "belief_map_refits": int(self.refits),
            "belief_map_representatives": self.representatives,
            "belief_map_cell_size_m": self.cell_size_m,
            "belief_map_snapshots": sorted(snapshots),
        }
