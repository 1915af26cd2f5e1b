"""The belief's summary: the estimate (the dominant cluster's pose and covariance) and the grid entropy, computed
from histograms they share and cached until the particles change.

    from mcl.summary import Summary, Estimate, Entropy, Grid

`Summary` is what `mcl.ParticleFilter` owns of its summary: the carpet and its grids (`Grid`), the histograms
`mcl.estimate` fills in one pass, the cached `Estimate` and `Entropy`, and the estimate's hysteresis anchor (the
previous estimate, preferred when no cluster holds half the weight). The filter's engine (`mcl.engine`) fills
the histograms and computes the estimate and the entropy into it; `group` gives the compiled step these
buffers.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numba
import numpy as np

from field.checks import ArgumentTypeError, integer, real

from .estimate import summary_buffers, summary_grid

if TYPE_CHECKING:
    from field import Field

MAX_GRID_CELLS = 5 * 10**7
"""The most cells the entropy or the estimate's histograms may have (the grid's cells times its bins)."""


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
        return (
            self.weight >= weight
            and position_std <= position_sigma
            and math.sqrt(max(self.covariance[2, 2], 0.0)) <= heading_sigma
        )


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

    position_cell: float = 0.1  # m
    orientation_bins: int = 36  # 10° bins
    cluster_cell: float = 0.5  # m, seed histogram of the estimate
    cluster_orientation_bins: int = 8
    cluster_radius: float = 0.75  # m, mean-shift kernel
    cluster_angle_radius: float = 0.8  # rad

    def __post_init__(self) -> None:
        # Cells of at least 1 cm and at most 3600 orientation bins: the histograms stay within memory.
        for name in ("position_cell", "cluster_cell", "cluster_radius"):
            real(name, getattr(self, name), 0.01, 100.0)
        real("cluster_angle_radius", self.cluster_angle_radius, 0.0, 10.0, low_open=True)
        integer("orientation_bins", self.orientation_bins, 1, 3600)
        integer("cluster_orientation_bins", self.cluster_orientation_bins, 1, 360)


SHIFT_ITERATIONS = 3  # mean-shift steps of the estimate's cluster (from a cell's centre, and from the last estimate)


class Summary:
    """The estimate and the entropy of a particle set on a field's carpet, cached until the particles change.

    Parameters
    ----------
    field : Field
        The field: the carpet is the field and its border strip.
    grid : Grid
        The entropy's and the estimate's cells.
    n : int
        The number of particles.
    threads : int
        The engine's threads: with more than one, each thread gets its own histograms.

    Raises
    ------
    ValueError
        If the grid makes more than `MAX_GRID_CELLS` cells on this field.
    ArgumentTypeError
        If `grid` is not a `Grid`.
    """

    shift_iterations = SHIFT_ITERATIONS  # the estimate's mean-shift steps (`mcl.reference.summary_estimate` reads it)

    def __init__(self, field: Field, grid: Grid, n: int, threads: int) -> None:
        if not isinstance(grid, Grid):
            raise ArgumentTypeError(f"grid = {grid!r} must be an mcl.Grid, not {type(grid).__name__}")
        self.grid = grid
        self.x_min, self.x_max, self.y_min, self.y_max = field.carpet
        self.entropy_nx = max(1, math.ceil((self.x_max - self.x_min) / grid.position_cell))
        self.entropy_ny = max(1, math.ceil((self.y_max - self.y_min) / grid.position_cell))
        self.cluster_nx = max(1, math.ceil((self.x_max - self.x_min) / grid.cluster_cell))
        self.cluster_ny = max(1, math.ceil((self.y_max - self.y_min) / grid.cluster_cell))
        for what, cells in (
            ("position", self.entropy_nx * self.entropy_ny * grid.orientation_bins),
            ("cluster", self.cluster_nx * self.cluster_ny * grid.cluster_orientation_bins),
        ):
            if cells > MAX_GRID_CELLS:
                raise ValueError(
                    f"grid = {grid!r} makes {cells} {what} cells on this field; at most "
                    f"{MAX_GRID_CELLS} are accepted (larger cells, fewer bins)"
                )
        self.parameters = summary_grid(
            self.x_min,
            self.y_min,
            grid.cluster_cell,
            self.cluster_nx,
            self.cluster_ny,
            grid.cluster_orientation_bins,
            grid.cluster_radius,
            grid.cluster_angle_radius,
            SHIFT_ITERATIONS,
            grid.position_cell,
            self.entropy_nx,
            self.entropy_ny,
            grid.orientation_bins,
        )
        self.coordinates, self.histograms, self.bitmaps = summary_buffers(self.parameters, n)
        # threads > 1: each thread's histograms, in fixed point (see mcl.estimate.summary_fill_chunked)
        self.local = np.zeros(
            (numba.config.NUMBA_NUM_THREADS if threads > 1 else 0, self.histograms.shape[0]), dtype=np.int64
        )
        self.valid = False  # whether the histograms are those of the particles as they are
        self.estimate: Estimate | None = None  # the cached estimate and entropy (None: stale)
        self.entropy: Entropy | None = None
        # Once the entropy has been asked for, the compiled step (and the estimate) computes it from the
        # histograms it fills anyway, sparing the call its own dispatch into compiled code.
        self.entropy_wanted = False
        self.previous = np.zeros(3)  # the hysteresis anchor: the last estimate's mean
        self.has_previous = False

    @property
    def carpet(self) -> tuple[float, float, float, float]:
        """The carpet's bounds (x_min, x_max, y_min, y_max) [m]: the field and its border strip."""
        return self.x_min, self.x_max, self.y_min, self.y_max

    @property
    def entropy_bounds(self) -> tuple[float, float]:
        """The largest possible position and orientation entropies: log2 of the cell counts."""
        return math.log2(self.entropy_nx * self.entropy_ny), math.log2(self.grid.orientation_bins)

    def changed(self) -> None:
        """The particles or their weights changed: the cached estimate, entropy and histograms are stale."""
        self.estimate = None
        self.entropy = None
        self.valid = False

    def forget_anchor(self) -> None:
        """The particles moved in a way the estimate's continuity cannot follow (set, mirrored, diffused): the
        next estimate starts without its hysteresis anchor, and the cached ones are stale (`changed`)."""
        self.has_previous = False
        self.changed()

    def group(
        self,
        want_estimate: bool,
        mean: np.ndarray,
        covariance: np.ndarray,
        use_previous: bool | None = None,
        want_entropy: bool | None = None,
    ) -> tuple:
        """The summary's arguments of the compiled step (`mcl.step`): the grid and its histograms, whether to
        compute the estimate (into `mean`, `covariance`; its hysteresis anchor) and the entropy."""
        return (
            self.parameters,
            self.coordinates,
            self.histograms,
            self.bitmaps,
            want_estimate,
            self.previous,
            self.has_previous if use_previous is None else use_previous,
            mean,
            covariance,
            self.entropy_wanted if want_entropy is None else want_entropy,
        )

    def keep(self, estimate: Estimate | None, position: float, orientation: float) -> None:
        """What a step computed with the histograms it filled: the estimate when it computed one (its anchor
        moved to it), and the entropy when it has been asked for."""
        self.valid = True
        if estimate is not None:
            self.estimate = estimate
            self.has_previous = True
        if self.entropy_wanted:
            self.entropy = Entropy(float(position), float(orientation))
