"""The belief's summary: the estimate (the dominant cluster's pose and covariance) and the grid entropy, computed
from histograms they share and cached until the particles change.

    from mcl.summary import BeliefSummary, Estimate, Entropy, Grid

`BeliefSummary` is the part of `mcl.ParticleFilter` that summarizes the particle set (`mcl.particles`): the
carpet and its grids (`Grid`), the histograms `mcl.estimate` fills in one pass, the cached `Estimate` and
`Entropy`, and the estimate's hysteresis anchor (the previous estimate, preferred when no cluster holds half the
weight). The fused compiled step (`mcl.step`) fills the same histograms and computes the same estimate in its
call; `_summary_group` gives it these buffers.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, ContextManager

import numba
import numpy as np

from field.checks import ArgumentTypeError, integer, real

from .estimate import (summary_buffers, summary_entropy, summary_estimate, summary_estimate_chunked,
                       summary_estimate_fast, summary_fill, summary_fill_chunked, summary_grid)
from .step import summarize

if TYPE_CHECKING:
    from field import Field

MAX_GRID_CELLS = 5 * 10**7
"""The most cells the entropy or the estimate's histograms may have (the grid's cells times its bins)."""
_NO_MEAN, _NO_COVARIANCE = np.empty(3), np.empty((3, 3))     # out_mean, out_cov of a summary without estimate


@dataclass(frozen=True)
class Estimate:
    """The pose of the dominant cluster: pose [x, y, θ], its covariance (3, 3), and the cluster's weight.

    Attributes
    ----------
    pose : np.ndarray
        (3,) float64 pose (x [m], y [m], θ [rad]) in the field frame.
    covariance : np.ndarray
        (3, 3) float64 covariance of the cluster's particles about `pose` [m², m·rad, rad²].
    weight : float
        The share of the particles' weight the cluster holds, in [0, 1].
    """

    pose: np.ndarray
    covariance: np.ndarray
    weight: float

    @property
    def x(self) -> float:
        """The estimate's x [m]."""
        return float(self.pose[0])

    @property
    def y(self) -> float:
        """The estimate's y [m]."""
        return float(self.pose[1])

    @property
    def theta(self) -> float:
        """The estimate's heading θ [rad]."""
        return float(self.pose[2])

    def is_confident(self, position_sigma: float = 0.3, heading_sigma: float = 0.2, weight: float = 0.8) -> bool:
        """True when the cluster holds most of the weight and is tight in position and heading.

        Parameters
        ----------
        position_sigma : float, optional
            The largest position spread sqrt(var x + var y) [m]; default 0.3.
        heading_sigma : float, optional
            The largest heading standard deviation [rad]; default 0.2.
        weight : float, optional
            The least weight share of the cluster; default 0.8.

        Returns
        -------
        bool
            True when all three hold.
        """
        position_std = math.sqrt(max(self.covariance[0, 0] + self.covariance[1, 1], 0.0))
        return (self.weight >= weight and position_std <= position_sigma
                and math.sqrt(max(self.covariance[2, 2], 0.0)) <= heading_sigma)

@dataclass(frozen=True)
class Entropy:
    """Grid entropy of the belief in bits (Hoffmann eq. 27).

    Attributes
    ----------
    position : float
        Entropy of the particles' weight over the position cells [bit].
    orientation : float
        Entropy over the orientation bins [bit].
    """

    position: float
    orientation: float

@dataclass(frozen=True)
class Grid:
    """Cell sizes for the entropy (and the estimate's seed histogram).

    Parameters
    ----------
    position_cell : float, optional
        Side of the entropy's position cells [m], within [0.01, 100]; default 0.1.
    orientation_bins : int, optional
        Orientation bins of the entropy, within [1, 3600]; default 36 (10°).
    cluster_cell : float, optional
        Side of the estimate's seed histogram cells [m], within [0.01, 100]; default 0.5.
    cluster_orientation_bins : int, optional
        Orientation bins of the seed histogram, within [1, 360]; default 8.
    cluster_radius : float, optional
        Position radius of the estimate's mean-shift kernel [m], within [0.01, 100]; default 0.75.
    cluster_angle_radius : float, optional
        Heading radius of the mean-shift kernel [rad], within (0, 10]; default 0.8.

    Raises
    ------
    ValueError
        If a value is out of range (TypeError, `field.checks.ArgumentTypeError`, for the wrong type).
    """

    position_cell: float = 0.1            # m
    orientation_bins: int = 36            # 10° bins
    cluster_cell: float = 0.5             # m, seed histogram of the estimate
    cluster_orientation_bins: int = 8
    cluster_radius: float = 0.75          # m, mean-shift kernel
    cluster_angle_radius: float = 0.8     # rad

    def __post_init__(self) -> None:
        # Cells of at least 1 cm and at most 3600 orientation bins: the histograms stay within memory.
        for name in ("position_cell", "cluster_cell", "cluster_radius"):
            real(name, getattr(self, name), 0.01, 100.0)
        real("cluster_angle_radius", self.cluster_angle_radius, 0.0, 10.0, low_open=True)
        integer("orientation_bins", self.orientation_bins, 1, 3600)
        integer("cluster_orientation_bins", self.cluster_orientation_bins, 1, 360)


class BeliefSummary:
    """The estimate and the entropy of the particle set, cached until it changes (see the module docstring)."""

    # Set by the filter that is also a `ParticleSet` (`mcl.filter.ParticleFilter`), declared for type checkers.
    _n: int
    _field: Field
    _poses: np.ndarray
    _weights: np.ndarray
    _threads: int
    _chunk: int
    _fast: bool
    _thread_scope: ContextManager[object]

    def _allocate_summary(self) -> None:
        """The histograms the estimate and the entropy share, and the summary's cached state."""
        # The estimate's and the entropy's histograms, filled in one pass and kept until the particles change.
        grid = self._grid
        self._grid_parameters = summary_grid(self._x_min, self._y_min, grid.cluster_cell, self._cluster_nx,
                                             self._cluster_ny, grid.cluster_orientation_bins, grid.cluster_radius,
                                             grid.cluster_angle_radius, 3, grid.position_cell, self._entropy_nx,
                                             self._entropy_ny, grid.orientation_bins)
        self._summary = summary_buffers(self._grid_parameters, self._n)
        # threads > 1: each thread's histograms, in fixed point (see mcl.estimate.summary_fill_chunked)
        self._local_histograms = np.zeros((numba.config.NUMBA_NUM_THREADS if self._threads > 1 else 0,
                                           self._summary[1].shape[0]), dtype=np.int64)
        self._summary_valid = False
        self._estimate: Estimate | None = None
        self._entropy: Entropy | None = None
        # Once `entropy()` has been asked for, the compiled step (and `estimate()`) computes the entropy from the
        # histograms it fills anyway, sparing the call its own dispatch into compiled code.
        self._entropy_wanted = False
        self._previous_estimate = np.zeros(3)
        self._has_previous_estimate = False

    def _forget_anchor(self) -> None:
        """The particles moved in a way the estimate's continuity cannot follow (set, mirrored, diffused): the
        next estimate starts without its hysteresis anchor."""
        self._has_previous_estimate = False

    def _set_up_grid(self, grid: Grid) -> None:
        """The carpet (the field and its border strip) and the entropy's and the estimate's grids on it."""
        if not isinstance(grid, Grid):
            raise ArgumentTypeError(f"grid = {grid!r} must be an mcl.Grid, not {type(grid).__name__}")
        self._grid = grid
        # Carpet bounds: the field plus its border strip.
        field = self._field
        border = field.dims.border_strip_width
        self._x_min, self._x_max = -field.half_length - border, field.half_length + border
        self._y_min, self._y_max = -field.half_width - border, field.half_width + border
        self._entropy_nx = max(1, math.ceil((self._x_max - self._x_min) / grid.position_cell))
        self._entropy_ny = max(1, math.ceil((self._y_max - self._y_min) / grid.position_cell))
        self._cluster_nx = max(1, math.ceil((self._x_max - self._x_min) / grid.cluster_cell))
        self._cluster_ny = max(1, math.ceil((self._y_max - self._y_min) / grid.cluster_cell))
        for what, cells in (("position", self._entropy_nx * self._entropy_ny * grid.orientation_bins),
                            ("cluster", self._cluster_nx * self._cluster_ny * grid.cluster_orientation_bins)):
            if cells > MAX_GRID_CELLS:
                raise ValueError(f"grid = {grid!r} makes {cells} {what} cells on this field; at most "
                                 f"{MAX_GRID_CELLS} are accepted (larger cells, fewer bins)")

    @property
    def grid(self) -> Grid:
        """The entropy and estimate grid (fixed: the filter's histograms are made for it)."""
        return self._grid

    @property
    def entropy_bounds(self) -> tuple[float, float]:
        """The largest possible position and orientation entropies: log2 of the cell counts."""
        return math.log2(self._entropy_nx * self._entropy_ny), math.log2(self._grid.orientation_bins)

    def _changed(self) -> None:
        """The particles or their weights changed: the cached estimate and summary histograms are stale."""
        self._estimate = None
        self._entropy = None
        self._summary_valid = False

    def _summary_group(self, want_estimate: bool, mean: np.ndarray, covariance: np.ndarray,
                       use_previous: bool | None = None, want_entropy: bool | None = None) -> tuple:
        """The summary's arguments of the compiled step (`mcl.step`): the grid and its histograms, whether to
        compute the estimate (into `mean`, `covariance`; its hysteresis anchor) and the entropy."""
        coordinates, histograms, bitmaps = self._summary
        return (self._grid_parameters, coordinates, histograms, bitmaps, want_estimate, self._previous_estimate,
                self._has_previous_estimate if use_previous is None else use_previous, mean, covariance,
                self._entropy_wanted if want_entropy is None else want_entropy)

    def _fill_summary(self) -> None:
        if not self._summary_valid:
            if self._threads > 1:
                with self._thread_scope:
                    summary_fill_chunked(self._grid_parameters, self._poses, self._weights, *self._summary,
                                         self._local_histograms, self._chunk)
            else:
                summary_fill(self._grid_parameters, self._poses, self._weights, *self._summary)
            self._summary_valid = True

    def estimate(self) -> Estimate:
        """Weighted circular mean and covariance of the dominant cluster (cached until the particles change).

        When no cluster holds half the weight, the one around the previous estimate is preferred if it is
        the heavier (hysteresis: see `mcl.estimate.cluster_estimate`).

        Returns
        -------
        Estimate
            The pose [x, y, θ], its (3, 3) covariance and the cluster's share of the weight.
        """
        if self._estimate is None:
            mean = np.empty(3)
            cov = np.empty((3, 3))
            previous = self._previous_estimate
            coordinates, histograms, bitmaps = self._summary
            if self._threads == 1 and not self._summary_valid:
                # One dispatch: the histograms, the estimate and (once asked for) the entropy.
                weight, position, orientation = summarize(self._poses, self._weights,
                                                          self._summary_group(True, mean, cov), self._fast)
                self._summary_valid = True
                if self._entropy_wanted:
                    self._entropy = Entropy(float(position), float(orientation))
            else:
                self._fill_summary()
                if self._threads > 1:
                    with self._thread_scope:
                        weight = summary_estimate_chunked(self._grid_parameters, coordinates, self._weights,
                                                          histograms, bitmaps, previous, self._has_previous_estimate,
                                                          mean, cov, self._chunk)
                elif self._fast:
                    weight = summary_estimate_fast(self._grid_parameters, coordinates, self._weights, histograms,
                                                   bitmaps, previous, self._has_previous_estimate, mean, cov)
                else:
                    weight = summary_estimate(self._grid_parameters, coordinates, self._weights, histograms,
                                              bitmaps, previous, self._has_previous_estimate, mean, cov)
                previous[:] = mean
            self._estimate = Estimate(mean, cov, float(weight))
            self._has_previous_estimate = True
        return self._estimate

    def entropy(self) -> Entropy:
        """Position and orientation entropy in bits on the grid (Hoffmann eq. 27), from the histograms the
        estimate shares (kept until the particles change).

        Returns
        -------
        Entropy
            `position` and `orientation`, in bits.
        """
        self._entropy_wanted = True
        if self._entropy is None:
            if self._threads == 1 and not self._summary_valid:
                # One dispatch: the histograms and the entropy (no estimate: it would move the hysteresis anchor).
                _, position, orientation = summarize(self._poses, self._weights, self._summary_group(
                    False, _NO_MEAN, _NO_COVARIANCE, use_previous=False, want_entropy=True), self._fast)
                self._summary_valid = True
            else:
                self._fill_summary()
                position, orientation = summary_entropy(self._grid_parameters, *self._summary[1:])
            self._entropy = Entropy(float(position), float(orientation))
        return self._entropy
