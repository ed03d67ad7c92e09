"""Local posteriors for regions larger than a sandbox: the BHM split into overlapping tiles.

A hinge weight is coupled to another only through observations that both features reach,
that is within a few length scales. A region of ``D`` hinges therefore need not hold one
dense ``D x D`` posterior: it is split into square tiles of ``T x T`` hinges (the *core*),
and each tile runs an ordinary dense BHM over its core plus a *halo* of ``H`` hinges on every
side, fed the observations that reach its core's neighbourhood:

- ``w`` is the kernel window half-width (:func:`._windowed.window_half_width`: features
  beyond ``w`` hinges from a point's nearest hinge are below 1e-6), ``H = 2 w``.
- A point whose nearest hinge lies within ``w`` hinges of a tile's core is fused into that
  tile: its whole window then lies inside the tile's hinges, so no feature is truncated. Each
  point goes to one to four tiles (more only when the core is narrower than a window).
- A point is predicted by the tile whose core holds its nearest hinge. Every hinge it
  reaches is within ``w`` of the core, and every observation that reaches those hinges was
  fused into the tile; only the coupling through hinges between ``w`` and ``2 w`` outside the
  core, to observations beyond the halo, is dropped.

Tiles are made when the first observation reaches them. Where none has, the map is the prior,
computed for any number of points without building a tile: every hinge weight has mean 0
and variance ``v``, so the activation has mean ``m_bias`` and variance
``v sum_i gx_i^2 sum_j gy_j^2 + v_bias`` (the Gaussian factorises per axis).

Memory is the tiles observed times ``(T + 2H)^4`` doubles (the Cholesky factor of each
posterior; precisions and covariances are kept for the last few tiles used only), time per
update the few tiles a batch reaches: both grow with the area observed, not with the square
of the region.
"""

from __future__ import annotations

from collections import OrderedDict
from collections.abc import Callable, Iterator

import numpy as np
from numpy.typing import NDArray

from hapticframe.kinds import Observations, Region

from . import _functional as fn
from ._config import BayesianHilbertMapConfig
from ._dense import DenseBelief, grid_axes
from ._windowed import window_half_width

__all__ = ["TileLayout", "TiledBeliefs"]

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.intp]

#: Tiles whose precision and covariance stay cached (each a (T + 2H)^2-square matrix).
_COVARIANCE_CACHE_TILES = 6
#: Distinct grids whose moments each tile keeps until it fuses again.
_GRIDS_KEPT = 2
#: Query points handled at once by the prior's separable formula.
_PRIOR_CHUNK = 8192


class TileLayout:
    """Which hinges each tile holds and which points it fuses and predicts.

    Parameters
    ----------
    nx, ny : int
        Hinges along each axis of the whole grid.
    core : int
        Hinges per side of a tile's core (``T``).
    reach : int
        Kernel window half-width ``w`` in hinges; the halo is ``2 w``.
    """

    def __init__(self, nx: int, ny: int, core: int, reach: int) -> None:
        if core < 1 or reach < 0:
            raise ValueError("a tile needs a core of at least one hinge and a reach >= 0")
        self.nx, self.ny, self.core, self.reach = int(nx), int(ny), int(core), int(reach)
        self.halo = 2 * self.reach
        self.tiles_x = -(-self.nx // self.core)
        self.tiles_y = -(-self.ny // self.core)

    def hinge_range(self, tile: tuple[int, int]) -> tuple[slice, slice]:
        """Slices of the global hinge axes held by ``tile`` (core plus halo, clipped)."""
        out = []
        for index, size in zip(tile, (self.nx, self.ny), strict=True):
            low = max(0, index * self.core - self.halo)
            high = min(size, (index + 1) * self.core + self.halo)
            out.append(slice(low, high))
        return out[0], out[1]

    def largest_tile_hinges(self) -> int:
        """Hinges of the largest tile."""
        side_x = min(self.nx, self.core + 2 * self.halo)
        side_y = min(self.ny, self.core + 2 * self.halo)
        return side_x * side_y

    def owners(self, ix: IntArray, iy: IntArray) -> IntArray:
        """Flat index ``a * tiles_y + b`` of the tile whose core holds each nearest hinge."""
        return (ix // self.core) * self.tiles_y + iy // self.core

    def fusing(self, ix: IntArray, iy: IntArray) -> Iterator[tuple[tuple[int, int], IntArray]]:
        """``(tile, rows)`` for every tile that fuses some of the points with nearest hinges
        ``(ix, iy)``: those within ``reach`` hinges of the tile's core."""
        per_axis = []
        for index, count in ((ix, self.tiles_x), (iy, self.tiles_y)):
            low = np.clip((index - self.reach) // self.core, 0, count - 1)
            high = np.clip((index + self.reach) // self.core, 0, count - 1)
            per_axis.append((low, high))
        (xl, xh), (yl, yh) = per_axis
        # A window spans at most this many tiles per axis (two unless the core is narrower
        # than the window).
        span = 2 * self.reach // self.core + 2
        key_parts, row_parts = [], []
        for ox in range(span):
            for oy in range(span):
                inside = np.flatnonzero((xl + ox <= xh) & (yl + oy <= yh))
                key_parts.append((xl[inside] + ox) * self.tiles_y + yl[inside] + oy)
                row_parts.append(inside)
        pairs = np.unique(np.concatenate(key_parts) * ix.size + np.concatenate(row_parts))
        keys, rows = np.divmod(pairs, ix.size)
        for key in np.unique(keys):
            a, b = divmod(int(key), self.tiles_y)
            yield (a, b), rows[keys == key]


class TiledBeliefs:
    """The tiles of a large BHM: a :class:`~hapticframe_bhm._dense.HilbertBelief` made of
    :class:`~hapticframe_bhm._dense.DenseBelief` tiles.

    Parameters
    ----------
    config : BayesianHilbertMapConfig
    xs, ys : (nx,), (ny,) float64
        The whole hinge grid.
    rng : numpy.random.Generator
        Draws the Monte-Carlo std of the prior where no tile exists, and the tiles' weight
        samples.
    name : str
        The map's id, for errors.
    """

    #: A tiled map reports no single update (each tile fuses its own part of a batch).
    last_update_info: fn.UpdateInfo | None = None

    def __init__(
        self,
        config: BayesianHilbertMapConfig,
        xs: FloatArray,
        ys: FloatArray,
        rng: np.random.Generator,
        name: str,
    ) -> None:
        self.config = config
        self.xs, self.ys = xs, ys
        spacing = config.hinge_spacing_m
        scale = max(config.length_scale_free_m,
                    config.length_scale_interaction_m if config.region_dependent_smoothing
                    else 0.0,
                    config.length_scale_free_m * config.automorphing_range[1]
                    if config.automorphing_kernels else 0.0)
        reach = window_half_width(scale, spacing)
        if config.tile_size_m is None:
            core = max(1, 2 * (2 * reach))
        else:
            core = max(1, round(config.tile_size_m / spacing))
        self.layout = TileLayout(xs.size, ys.size, core, reach)
        self._rng = rng
        self._name = name
        # Tiles of one size share one prior (it is only read): its dense diagonal matrices
        # would otherwise double the memory of the tiles.
        self._priors: dict[int, fn.GaussianWeights] = {}
        self.tiles: dict[tuple[int, int], DenseBelief] = {}
        self._covariances: OrderedDict[tuple[int, int], None] = OrderedDict()
        self._packed: dict[tuple[int, int], tuple[FloatArray, FloatArray, FloatArray]] = {}
        self._tril: dict[int, tuple[IntArray, IntArray]] = {}
        # Each tile's last grid moments, kept until the tile fuses again: a grid query (a
        # recorded map snapshot) then costs in proportion to the tiles that changed, not to
        # the region (every tile's covariance rebuilt per snapshot made a 3 x 2 m
        # recording +30 % CPU).
        # Per tile, the grids of the last _GRIDS_KEPT distinct queries: a recorded run asks
        # for two grids in turn (the snapshot's and the planner's), which one entry per tile
        # made recompute every tile on each (a 10 x 10 m recording +20 % CPU).
        self._grid_moments: dict[
            tuple[int, int], OrderedDict[tuple[bytes, bytes], tuple[FloatArray, FloatArray]]
        ] = {}

    def reset(self) -> None:
        """Drop every tile: the whole region is the prior again."""
        self.tiles.clear()
        self._covariances.clear()
        self._packed.clear()
        self._grid_moments.clear()

    # --- points to hinges -----------------------------------------------------------------

    def _nearest(self, points: FloatArray) -> tuple[IntArray, IntArray]:
        spacing = self.config.hinge_spacing_m
        out = []
        for axis, hinges in ((0, self.xs), (1, self.ys)):
            index = np.rint((points[:, axis] - hinges[0]) / spacing)
            out.append(np.clip(index, 0, hinges.size - 1).astype(np.intp))
        return out[0], out[1]

    def _make_tile(self, xs: FloatArray, ys: FloatArray) -> DenseBelief:
        """A dense belief with the map's settings over the hinge sub-grid ``xs x ys``."""
        region = Region(float(xs[0]), float(xs[-1]), float(ys[0]), float(ys[-1]))
        dimension = xs.size * ys.size + int(self.config.bias)
        tile = DenseBelief(self.config, region, xs, ys, self._rng, self._name,
                           self._priors.get(dimension))
        self._priors.setdefault(dimension, tile.prior)
        return tile

    def _tile(self, tile: tuple[int, int]) -> DenseBelief:
        """The tile, made if new, its belief unpacked if it was evicted."""
        existing = self.tiles.get(tile)
        if existing is None:
            sx, sy = self.layout.hinge_range(tile)
            existing = self._make_tile(self.xs[sx], self.ys[sy])
            self.tiles[tile] = existing
        packed = self._packed.pop(tile, None)
        if packed is not None:
            factor, shift, mean = packed
            lower = np.zeros((mean.size, mean.size))
            lower[self._lower_indices(mean.size)] = factor
            existing.posterior = fn.GaussianWeights(shift, lower, mean)
        return existing

    def _lower_indices(self, dimension: int) -> tuple[IntArray, IntArray]:
        indices = self._tril.get(dimension)
        if indices is None:
            indices = self._tril[dimension] = np.tril_indices(dimension)
        return indices

    def _touched(self, tile: tuple[int, int]) -> None:
        """Keep the beliefs of the last few tiles used whole; pack the oldest: its lower
        Cholesky factor alone, half of one square matrix (the precision and covariance are
        rebuilt from it when the tile is used again)."""
        self._covariances.pop(tile, None)
        self._covariances[tile] = None
        while len(self._covariances) > _COVARIANCE_CACHE_TILES:
            old, _ = self._covariances.popitem(last=False)
            dense = self.tiles.get(old)
            if dense is None or old in self._packed or dense.posterior.diagonal:
                continue
            belief = dense.posterior
            factor = belief.cholesky[self._lower_indices(belief.dimension)]
            self._packed[old] = (factor, belief.shift, belief.mean)
            del dense.posterior  # until _tile unpacks it

    # --- updates --------------------------------------------------------------------------

    def update(self, observations: Observations) -> None:
        """Fuse the batch into every tile it reaches."""
        ix, iy = self._nearest(observations.points_m)
        for tile, rows in self.layout.fusing(ix, iy):
            part = Observations(
                observations.points_m[rows], observations.targets[rows],
                observations.weights[rows],
            )
            self._grid_moments.pop(tile, None)
            self._tile(tile).update(part)
            self._touched(tile)

    # --- queries --------------------------------------------------------------------------

    def _squared_feature_sums(self, coordinates: FloatArray, hinges: FloatArray) -> FloatArray:
        """``sum_i exp(-(c - h_i)^2 / (2 l^2))^2`` per coordinate, in bounded chunks."""
        out = np.empty(coordinates.size)
        for start in range(0, coordinates.size, _PRIOR_CHUNK):
            block = coordinates[start : start + _PRIOR_CHUNK, None] - hinges[None, :]
            out[start : start + block.shape[0]] = (
                fn._gaussian_factor(block, self.config.length_scale_free_m) ** 2
            ).sum(axis=1)
        return out

    def _prior_terms(self) -> tuple[float, float]:
        """Prior activation mean and the variance of the bias weight (0 without bias)."""
        cfg = self.config
        if not cfg.bias:
            return 0.0, 0.0
        return float(np.log(cfg.prior_occupancy / (1.0 - cfg.prior_occupancy))), cfg.prior_variance

    def prior_moments(self, points: FloatArray) -> tuple[FloatArray, FloatArray]:
        """Activation mean and variance under the prior (no tile reaches ``points``)."""
        mean, bias_variance = self._prior_terms()
        var = self.config.prior_variance * self._squared_feature_sums(points[:, 0], self.xs)
        var *= self._squared_feature_sums(points[:, 1], self.ys)
        return np.full(points.shape[0], mean), var + bias_variance

    def _prior_estimate(
        self, points: FloatArray, moments: tuple[FloatArray, FloatArray] | None = None
    ) -> tuple[FloatArray, FloatArray]:
        mu, var = self.prior_moments(points) if moments is None else moments
        mean = fn.probit_probability(mu, var)
        if self.config.std_method == "surrogate":
            return mean, fn.surrogate_std(mu, var)
        # The activation is Gaussian under the prior: sample it per point (same marginal as
        # sampling the weights; points are not jointly sampled).
        std = np.empty(mu.size)
        count = self.config.monte_carlo_samples
        chunk = max(1, _PRIOR_CHUNK * 16 // count)
        for start in range(0, mu.size, chunk):
            rows = slice(start, start + chunk)
            z = self._rng.standard_normal((mu[rows].size, count))
            activations = mu[rows, None] + np.sqrt(var[rows])[:, None] * z
            std[rows] = fn.monte_carlo_probability(activations)[1]
        return mean, std

    def query(self, points: FloatArray) -> tuple[FloatArray, FloatArray]:
        """Occupancy mean and std at ``points``, each from the tile that owns it (a
        row-major grid: :meth:`grid_moments`)."""
        axes = grid_axes(points)
        if axes is not None:
            mean_grid, std_grid = self.grid_moments(*axes)
            return mean_grid.reshape(-1), std_grid.reshape(-1)
        mean, std = self._prior_estimate(points)
        if not self.tiles or points.shape[0] == 0:
            return mean, std
        owner = self.layout.owners(*self._nearest(points))
        for tile in list(self.tiles):
            rows = np.flatnonzero(owner == tile[0] * self.layout.tiles_y + tile[1])
            if rows.size:
                mean[rows], std[rows] = self._tile(tile).query(points[rows])
                self._touched(tile)
        return mean, std

    def log_odds(self, points: FloatArray) -> FloatArray:
        """``kappa mu_a`` at ``points``."""
        if points.shape[0] == 0:
            return np.empty(0)
        mu, var = self.prior_moments(points)
        out = fn.probit_kappa(var) * mu
        owner = self.layout.owners(*self._nearest(points))
        for tile in list(self.tiles):
            rows = np.flatnonzero(owner == tile[0] * self.layout.tiles_y + tile[1])
            if rows.size:
                out[rows] = self._tile(tile).log_odds(points[rows])
                self._touched(tile)
        return out

    def grid_moments(self, qx: FloatArray, qy: FloatArray) -> tuple[FloatArray, FloatArray]:
        """Mean and std, ``(len(qy), len(qx))``, tile by tile on the grid ``qx x qy``."""
        # The prior on a grid is separable: an outer product of per-axis sums.
        prior_mean, bias_variance = self._prior_terms()
        var = np.outer(self._squared_feature_sums(qy, self.ys),
                       self.config.prior_variance * self._squared_feature_sums(qx, self.xs))
        var += bias_variance
        mu = np.full(var.shape, prior_mean)
        mean, std = self._prior_estimate(np.empty((0, 2)), (mu.ravel(), var.ravel()))
        mean, std = mean.reshape(qy.size, qx.size), std.reshape(qy.size, qx.size)
        spacing = self.config.hinge_spacing_m
        core = self.layout.core
        column_tile = np.clip(np.rint((qx - self.xs[0]) / spacing), 0, self.xs.size - 1) // core
        row_tile = np.clip(np.rint((qy - self.ys[0]) / spacing), 0, self.ys.size - 1) // core
        for tile in list(self.tiles):
            columns = np.flatnonzero(column_tile == tile[0])
            rows = np.flatnonzero(row_tile == tile[1])
            if columns.size and rows.size:
                # Contiguous runs: the tile's cells are a rectangle of the grid.
                tile_qx, tile_qy = qx[columns], qy[rows]
                key = (tile_qx.tobytes(), tile_qy.tobytes())
                kept = self._grid_moments.setdefault(tile, OrderedDict())
                cached = kept.get(key)
                if cached is not None:
                    part_mean, part_std = cached
                    kept.move_to_end(key)
                else:
                    part_mean, part_std = self._read_only(tile).grid_moments(tile_qx, tile_qy)
                    self._repack(tile)
                    kept[key] = (part_mean, part_std)
                    if len(kept) > _GRIDS_KEPT:
                        kept.popitem(last=False)
                block = (slice(rows[0], rows[-1] + 1), slice(columns[0], columns[-1] + 1))
                mean[block], std[block] = part_mean, part_std
        return mean, std

    def _read_only(self, tile: tuple[int, int]) -> DenseBelief:
        """The tile's belief for a read that leaves the cache of whole beliefs as it was: a
        grid query (a recorded snapshot) reads every tile, and marking them all as used
        packed the beliefs the run was fusing into, which then rebuilt their covariances
        (a 10 x 10 m recording +50 % CPU)."""
        packed = self._packed.get(tile)
        dense = self._tile(tile)
        if packed is not None:
            self._packed[tile] = packed  # _tile popped it; _repack drops the whole belief
        return dense

    def _repack(self, tile: tuple[int, int]) -> None:
        """Drop the whole belief :meth:`_read_only` unpacked from a packed tile."""
        if tile in self._packed:
            dense = self.tiles[tile]
            if hasattr(dense, "posterior"):
                del dense.posterior

    # --- state of the whole grid ----------------------------------------------------------

    @property
    def interaction_hinges(self) -> NDArray[np.bool_]:
        return self.core_values(lambda t: t.interaction_hinges, False).astype(bool)

    @property
    def length_scales(self) -> FloatArray:
        scales = self.core_values(lambda t: t.length_scales, self.config.length_scale_free_m)
        return np.asarray(scales, dtype=np.float64)

    @property
    def batches_fused(self) -> int:
        """The most batches any tile fused."""
        return max((t.batches_fused for t in self.tiles.values()), default=0)

    @property
    def refits(self) -> int:
        """Refits summed over the tiles."""
        return sum(t.refits for t in self.tiles.values())

    def core_values(self, values: Callable[[DenseBelief], NDArray[np.generic]],
                    fill: float | bool) -> NDArray[np.generic]:
        """``(nx, ny)`` array of a per-hinge tile property, each hinge from its tile's core."""
        out = np.full((self.xs.size, self.ys.size), fill)
        core = self.layout.core
        for tile in list(self.tiles):
            sx, sy = self.layout.hinge_range(tile)
            cx = slice(tile[0] * core, min(self.xs.size, (tile[0] + 1) * core))
            cy = slice(tile[1] * core, min(self.ys.size, (tile[1] + 1) * core))
            local = values(self.tiles[tile])
            out[cx, cy] = local[cx.start - sx.start : cx.stop - sx.start,
                                cy.start - sy.start : cy.stop - sy.start]
        return out
