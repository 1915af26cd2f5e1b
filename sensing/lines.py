"""The field-line sensor model: points on detected lines scored against a likelihood field of the lines.

    from sensing import LineSensorModel
    model = LineSensorModel(spl())                       # precomputes the distance map once
    log_likelihood = model.log_likelihood(poses, observations)      # uses observations.line_points

As in nav2_amcl's likelihood-field model and Bit-Bots' localization: a distance transform
(`scipy.ndimage.distance_transform_edt`) of the rasterized line centre lines gives, for every cell of the
carpet, the distance d to the nearest line. A line point p seen in the robot frame scores, for a particle at
pose x, log(exp(-½(d(x ⊕ p)/σ)²) + outlier_weight). Points beyond the map score the floor. Neighbouring points
on a line are not independent, so at most `max_points` (spread evenly over the detections) are used. The
factor exp(-½(d/σ)²) + outlier_weight of every cell is computed once with the map (the likelihood field
proper, as B-Human keeps it), so scoring a point is a lookup and a multiplication.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from dataclasses import field as dataclass_field
from typing import TYPE_CHECKING

import numba
import numpy as np

from field import Field
from field.checks import LARGEST_SIGMA, SMALLEST_SIGMA, ArgumentTypeError, integer, real
from field.moved import moved_methods, moved_names
from numerics.frozen import keeps_arrays_frozen
from numerics.trig import sincos

from . import reference
from .observations import Observations

# The numpy twins moved to the package's `reference` module; their old names still work, with a warning.
__getattr__ = moved_names(__name__, {"line_log_likelihood_reference": "sensing.reference.line_log_likelihood"})


@numba.njit(cache=True)
def line_factors(distance, inv_var, log_outlier):
    """The likelihood field: exp(-½ d²/σ²) + outlier for every cell of the distance map, the factor a line
    point falling in that cell contributes to a particle's likelihood (computed once per model, so that
    scoring needs no exp per point)."""
    outlier = math.exp(log_outlier)
    out = np.empty_like(distance)
    for row in range(distance.shape[0]):
        for col in range(distance.shape[1]):
            d = distance[row, col]
            out[row, col] = math.exp(-0.5 * d * d * inv_var) + outlier
    return out


@numba.njit(cache=True)
def line_log_likelihood(poses, points, factors, x0, y0, inverse_cell, outlier, out):
    """out[i] = Σ_points log(exp(-½ d²/σ²) + outlier), the factor looked up in the likelihood field
    (`line_factors`, nearest cell); `outlier` beyond it."""
    ny, nx = factors.shape
    m = points.shape[0]
    for i in range(poses.shape[0]):
        c, s = sincos(poses[i, 2])
        total = 0.0
        product = 1.0
        for j in range(m):
            gx = poses[i, 0] + c * points[j, 0] - s * points[j, 1]
            gy = poses[i, 1] + s * points[j, 0] + c * points[j, 1]
            col = int(math.floor((gx - x0) * inverse_cell))
            row = int(math.floor((gy - y0) * inverse_cell))
            if 0 <= col < nx and 0 <= row < ny:
                product *= factors[row, col]
            else:
                product *= outlier
            if (j & 15) == 15:  # each factor is in (outlier, 1 + outlier]: flush before it can underflow
                total += math.log(product)
                product = 1.0
        out[i] = total + math.log(product)
    return out


MIN_RESOLUTION = 0.005
"""The finest likelihood-field cell accepted (m)."""
MAX_CELLS = 2 * 10**7
"""The most cells a likelihood field may have (two float64 maps of this size: 320 MB)."""


@keeps_arrays_frozen
@dataclass(frozen=True, eq=False)
class LineSensorModel:
    """Likelihood field of the field lines. sigma [m]: spread of a line point around its line.

    Parameters
    ----------
    field : Field
        The field whose lines are scored.
    sigma : float, optional
        Spread of a detected line point around its line [m]; default 0.1.
    resolution : float, optional
        Cell size of the likelihood field [m], within [`MIN_RESOLUTION`, 1]; default 0.02.
    max_points : int, optional
        The most line points scored per frame (spread evenly over the detections); default 12.
    outlier_weight : float, optional
        Likelihood floor of a point far from every line, in (0, 1]; default 0.05.

    Raises
    ------
    ValueError
        If a value is out of range or the field would have more than `MAX_CELLS` cells; TypeError
        (`field.checks.ArgumentTypeError`) if `field` is not a `Field`.
    """

    field: Field
    sigma: float = 0.1
    resolution: float = 0.02
    max_points: int = 12
    outlier_weight: float = 0.05
    _distance: np.ndarray = dataclass_field(init=False, repr=False)
    _factors: np.ndarray = dataclass_field(init=False, repr=False)
    _outlier: float = dataclass_field(init=False, repr=False)
    _origin: tuple[float, float] = dataclass_field(init=False, repr=False)

    def __post_init__(self) -> None:
        if not isinstance(self.field, Field):
            raise ArgumentTypeError(f"field = {self.field!r} must be a field.Field, not {type(self.field).__name__}")
        real("sigma", self.sigma, SMALLEST_SIGMA, LARGEST_SIGMA)
        real("resolution", self.resolution, MIN_RESOLUTION, 1.0)
        real("outlier_weight", self.outlier_weight, 0.0, 1.0, low_open=True)
        integer("max_points", self.max_points, 1, 10**6)
        x0, x_max, y0, y_max = self.field.carpet
        nx = math.ceil((x_max - x0) / self.resolution)
        ny = math.ceil((y_max - y0) / self.resolution)
        if nx * ny > MAX_CELLS:
            raise ValueError(
                f"resolution = {self.resolution!r} makes {nx * ny} cells on field {self.field.name!r}; "
                f"at most {MAX_CELLS} are accepted (a coarser resolution)"
            )
        on_line = np.ones((ny, nx), dtype=bool)  # True = not a line cell (the transform measures to False)
        points = self.field.line_points(spacing=self.resolution / 2)
        cols = np.clip(((points[:, 0] - x0) / self.resolution).astype(np.int64), 0, nx - 1)
        rows = np.clip(((points[:, 1] - y0) / self.resolution).astype(np.int64), 0, ny - 1)
        on_line[rows, cols] = False
        from scipy import ndimage  # here, not at module level: `import sensing` stays light

        distance = ndimage.distance_transform_edt(on_line) * self.resolution
        distance = np.ascontiguousarray(distance, dtype=np.float64)
        distance.flags.writeable = False
        object.__setattr__(self, "_distance", distance)
        log_outlier = math.log(self.outlier_weight)
        factors = line_factors(distance, 1.0 / self.sigma**2, log_outlier)
        factors.flags.writeable = False
        object.__setattr__(self, "_factors", factors)
        object.__setattr__(self, "_outlier", math.exp(log_outlier))
        object.__setattr__(self, "_origin", (x0, y0))

    @property
    def distance_map(self) -> np.ndarray:
        """(rows, cols) distance to the nearest line [m]; row = y, col = x, cell (0, 0) at the carpet corner."""
        return self._distance

    def check(self, observations: Observations) -> None:
        """Line points need no field-specific check (they were validated as finite when built).

        Parameters
        ----------
        observations : Observations
            One camera frame's detections (accepted as they are).
        """

    def used_points(self, observations: Observations) -> np.ndarray:
        """The at most `max_points` line points scored, spread evenly over the detections.

        Parameters
        ----------
        observations : Observations
            One camera frame's detections.

        Returns
        -------
        np.ndarray
            (P, 2) float64 line points in the robot frame [m], P <= `max_points`.
        """
        points = observations.line_points
        if points.shape[0] <= self.max_points:
            return points
        index = np.linspace(0, points.shape[0] - 1, self.max_points).round().astype(np.int64)
        return np.ascontiguousarray(points[index])

    def terms(self, observations: Observations) -> int:
        """How many independent terms the likelihood sums (for the filter's per-term fit): the number of line
        points scored.

        Parameters
        ----------
        observations : Observations
            As `used_points`.
        """
        return int(self.used_points(observations).shape[0])

    def log_likelihood(
        self, poses: np.ndarray, observations: Observations, out: np.ndarray | None = None
    ) -> np.ndarray:
        """(N,) log-likelihoods of the frame's line points at `poses`: Σ log(exp(-½ d²/σ²) + outlier_weight),
        d the distance of a point to the nearest line (looked up in the likelihood field, nearest cell).

        Parameters
        ----------
        poses, observations, out
            As `mcl.contracts.SensorModel.log_likelihood` (observations: anything `Observations.coerce`
            accepts; landmarks are ignored). Zeros when the frame has no line points.
        """
        observations = Observations.coerce(observations)
        out = np.empty(poses.shape[0]) if out is None else out
        points = self.used_points(observations)
        if points.shape[0] == 0:
            out[:] = 0.0
            return out
        x0, y0 = self._origin
        return line_log_likelihood(poses, points, self._factors, x0, y0, 1.0 / self.resolution, self._outlier, out)

    def numpy_twin(self) -> reference.LineTwin:
        """This model computed in plain numpy (`sensing.reference.LineTwin`): its `log_likelihood` from the
        distance map (exp per point), for the reference engine and the tests."""
        return reference.LineTwin(self)

    if not TYPE_CHECKING:  # the deprecated names (a type checker would accept any attribute after a __getattr__)
        __getattr__ = moved_methods(
            "LineSensorModel",
            {"log_likelihood_reference": ("numpy_twin().log_likelihood", lambda m: m.numpy_twin().log_likelihood)},
        )
