"""Recording a filter run to Rerun (.rrd) for review in the Rerun viewer.

    from mcl.recording import Recorder
    with Recorder("walk.rrd", field, particles_every=5) as rec:
        for step, t in ...:
            ...
            rec.log_step(step, t, pf, truth=true_pose, observations=obs)

Entity paths: `field/...` (static: lines, centre circle, landmarks by type), `particles` (every k-th step,
coloured by weight), `robot/estimate`, `robot/truth`, `observations` (arrows from the estimate to each
detection), `entropy/position`, `entropy/orientation` (every step), `error/position`, `error/heading` (when
the truth is known); timelines `step` (sequence) and `time` (duration, seconds). Anything else (a model's
state belief, a percept) goes through `log_scalars`. The file opens on a blueprint with the field view beside
the entropy and error plots. Data are logged in the field frame, in metres. Rerun's 2-D view draws +y
downwards (the image convention), so each top-level entity carries a static y-flip transform and the field
appears as seen from above (+x right, +y up); the viewer's hover readout is in the view's coordinates (y
negated), its selection panel shows the logged field-frame values.

Logged arrays are fresh copies (or a detection batch's own read-only arrays): Rerun keeps a reference until it
flushes. `close()` (or the `with` block) writes the file's footer. Everything a step logs is buffered and sent
as columns every `flush_every` steps (sooner when the buffered particles reach `max_points`): one
`send_columns` call costs what one `log` call does, about 250 µs. The per-step series (entropy, errors, the
pose arrows, `log_scalars`) are one row per step; the particles and the detection rays, whose lengths change
from step to step, are partitioned columns (a row of N points, a row of as many rays as detections). A step
with 10 detections and its particles took about 350 µs at N = 100 logged call by call, most of it the two
`log` calls. What remains per step is kept small: the particles' colours come from one compiled pass
(`weight_colors`), and the detection arrows are computed for all the buffered steps at once when they are sent
(see `robocup-mcl bench`'s recording phase for this version's figure).
"""
from __future__ import annotations

import math
from pathlib import Path

import numba
import numpy as np
import rerun as rr
import rerun.blueprint as rrb

from field import Field, LandmarkType
from field.checks import ArgumentTypeError, integer, real, reals
from sensing.observations import Observations

LANDMARK_COLORS = {
    LandmarkType.GOALPOST: (255, 255, 0),
    LandmarkType.L_CROSSING: (255, 120, 0),
    LandmarkType.T_CROSSING: (0, 200, 255),
    LandmarkType.X_CROSSING: (255, 0, 255),
    LandmarkType.PENALTY_MARK: (255, 255, 255),
    LandmarkType.CENTER_MARK: (200, 200, 200),
}

ARROW_COLORS = {"robot/estimate": (255, 60, 60), "robot/truth": (60, 255, 60)}
# LANDMARK_COLORS indexed by a detection's type value, for a whole batch at once.
LANDMARK_PALETTE = np.zeros((max(kind.value for kind in LandmarkType) + 1, 3), dtype=np.uint8)
for _kind, _color in LANDMARK_COLORS.items():
    LANDMARK_PALETTE[_kind.value] = _color
PARTICLE_RADIUS = 0.025
RAY_RADIUS = 0.01


_LOW = np.array([40.0, 30.0, 120.0])        # the lightest particle's colour (dark blue)
_HIGH = np.array([255.0, 230.0, 40.0])      # the heaviest's (yellow)


def weight_colors(weights: np.ndarray) -> np.ndarray:
    """Map weights to RGB (N, 3) uint8 from dark blue (lightest) to yellow (heaviest), relative to the heaviest
    (all dark blue when the heaviest is not positive). One pass in compiled code (`weight_colors_reference`,
    bit for bit): numpy's half a dozen passes and (N, 3) temporaries cost more than the rest of a step's
    recording at N >= 10 000, and their calls more than the particles at N = 100."""
    weights = np.ascontiguousarray(weights, dtype=np.float64)
    out = np.empty((weights.shape[0], 3), dtype=np.uint8)
    _weight_colors(weights, _LOW, _HIGH, out)
    return out


@numba.njit(cache=True)
def _weight_colors(weights, low, high, out):
    n = weights.shape[0]
    top = 1.0
    if n > 0:
        top = weights[0]
        for i in range(1, n):
            w = weights[i]
            if w > top or w != w:             # np.max: the largest, NaN if there is one
                top = w
                if w != w:
                    break
    if not top > 0.0:
        for i in range(n):
            for k in range(3):
                out[i, k] = np.uint8(low[k])
        return
    d0, d1, d2 = high[0] - low[0], high[1] - low[1], high[2] - low[2]
    for i in range(n):
        level = weights[i] / top
        level = 0.0 if level < 0.0 else level     # np.clip (a NaN stays NaN)
        level = 1.0 if level > 1.0 else level
        out[i, 0] = np.uint8(low[0] + level * d0)
        out[i, 1] = np.uint8(low[1] + level * d1)
        out[i, 2] = np.uint8(low[2] + level * d2)


def weight_colors_reference(weights: np.ndarray) -> np.ndarray:
    """Plain numpy twin of `weight_colors`."""
    top = float(weights.max()) if weights.size else 1.0
    level = np.clip(weights / top, 0.0, 1.0) if top > 0 else np.zeros_like(weights)
    return (_LOW + level[:, None] * (_HIGH - _LOW)).astype(np.uint8)


def default_blueprint(series: tuple[tuple[str, str], ...] = (("/entropy", "entropy [bits]"),
                                                              ("/error", "error [m, rad]"))) -> rrb.Blueprint:
    """The field view beside a column of time-series plots, one per (entity origin, title) in `series`."""
    return rrb.Blueprint(
        rrb.Horizontal(
            rrb.Spatial2DView(origin="/", name="field",
                              contents=["/field/**", "/particles", "/robot/**", "/observations"]),
            rrb.Vertical(*(rrb.TimeSeriesView(origin=origin, name=name) for origin, name in series)),
            column_shares=[3, 2],
        ),
        collapse_panels=True,
    )


def _step_and_time(step, t) -> tuple[int, float]:
    return integer("step", step, 0, 2**62), real("t", t)


class Recorder:
    """Writes one filter run to an .rrd file (or to any `rr.RecordingStream` you pass)."""

    def __init__(self, path: str | Path | None, field: Field, particles_every: int = 5,
                 application_id: str = "robocup-mcl", stream: rr.RecordingStream | None = None,
                 blueprint: rrb.Blueprint | None = None, flush_every: int = 200,
                 max_points: int = 1_000_000) -> None:
        for name, value in (("particles_every", particles_every), ("flush_every", flush_every),
                            ("max_points", max_points)):
            if isinstance(value, bool) or not isinstance(value, int) or value < 1:
                raise ValueError(f"{name} = {value!r} must be an integer >= 1")
        self.flush_every = flush_every
        self.max_points = max_points
        self._step, self._time = 0, 0.0
        self._scalars: dict[str, list[tuple[int, float, float]]] = {}
        self._arrows: dict[str, list[tuple[int, float, float, float, float, float]]] = {}
        # Rows of varying length: (step, time, arrays of one row each), sent as partitioned columns.
        self._particles: list[tuple[int, float, np.ndarray, np.ndarray]] = []
        self._rays: list[tuple[int, float, np.ndarray, np.ndarray, np.ndarray, tuple]] = []
        self._buffered_points = 0
        self._buffered_steps = 0
        if stream is None and path is None:
            raise ValueError("give a path or a stream")
        self.field = field
        self.particles_every = particles_every
        self.path = None if path is None else Path(path)
        self.stream = stream or rr.RecordingStream(application_id)
        if self.path is not None:
            self.path.parent.mkdir(parents=True, exist_ok=True)
            self.stream.save(str(self.path), default_blueprint=blueprint or default_blueprint())
        self._log_field()

    def __enter__(self) -> "Recorder":
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def close(self) -> None:
        """Send what is buffered, flush and write the footer."""
        self.flush()
        self.stream.disconnect()

    def flush(self) -> None:
        """Send what is buffered (the series, the particles and the detection arrows) as columns."""
        for path, rows in self._scalars.items():
            if rows:
                steps, times, values = (np.array(column) for column in zip(*rows))
                self.stream.send_columns(path, indexes=self._indexes(steps, times),
                                         columns=rr.Scalars.columns(scalars=values))
        for path, rows in self._arrows.items():
            if rows:
                table = np.array(rows)
                n = table.shape[0]
                color = np.tile(np.array(ARROW_COLORS[path] + (255,), dtype=np.uint8), (n, 1))
                self.stream.send_columns(path, indexes=self._indexes(table[:, 0].astype(np.int64), table[:, 1]),
                                         columns=rr.Arrows2D.columns(origins=table[:, 2:4], vectors=table[:, 4:6],
                                                                     colors=color, radii=np.full(n, 0.03)))
        if self._particles:
            self._send_rows("particles", self._particles, PARTICLE_RADIUS, lambda lengths, positions, colors, radii:
                            rr.Points2D.columns(positions=positions, colors=colors, radii=radii))
        if self._rays:
            self._send_rows("observations", self._rays, RAY_RADIUS, self._ray_columns)
        self._scalars = {}
        self._arrows = {}
        self._particles = []
        self._rays = []
        self._buffered_points = 0
        self._buffered_steps = 0

    def _send_rows(self, path: str, rows: list, radius: float, columns) -> None:
        """Rows (step, time, arrays of that step's entries[, a tuple of that step's values]) as one send of
        partitioned columns: columns(row lengths, *arrays concatenated over the rows[, the tuples as an array
        of one row per step], radii) makes them."""
        steps, times, *arrays = zip(*rows)
        lengths = [entries.shape[0] for entries in arrays[0]]
        batch = columns(lengths, *(np.array(parts) if isinstance(parts[0], tuple) else np.concatenate(parts)
                                   for parts in arrays), np.full(sum(lengths), radius, dtype=np.float32))
        self.stream.send_columns(path, indexes=self._indexes(np.array(steps), np.array(times)),
                                 columns=batch.partition(lengths))

    @staticmethod
    def _ray_columns(lengths, ranges, bearings, kinds, estimates, radii):
        """The detection arrows of buffered rows: from the estimate at each row's step (`estimates`, one
        (x, y, cos θ, sin θ) per row) to each detection, in the field frame."""
        px, py = ranges * np.cos(bearings), ranges * np.sin(bearings)       # `Observations.points`
        frames = np.repeat(estimates, lengths, axis=0)
        c, s = frames[:, 2], frames[:, 3]
        vectors = np.stack([c * px - s * py, s * px + c * py], axis=1)
        return rr.Arrows2D.columns(origins=frames[:, :2], vectors=vectors, colors=LANDMARK_PALETTE[kinds],
                                   radii=radii)

    @staticmethod
    def _indexes(steps: np.ndarray, times: np.ndarray) -> list:
        return [rr.TimeColumn("step", sequence=steps), rr.TimeColumn("time", duration=times)]

    def _scalar(self, path: str, value: float) -> None:
        self._scalars.setdefault(path, []).append((self._step, self._time, float(value)))

    def _arrow(self, path: str, pose: np.ndarray) -> None:
        self._arrows.setdefault(path, []).append((self._step, self._time, float(pose[0]), float(pose[1]),
                                                  0.35 * math.cos(pose[2]), 0.35 * math.sin(pose[2])))

    def _log_field(self) -> None:
        log = self.stream.log
        for root in ("field", "particles", "robot", "observations"):
            log(root, rr.Transform3D(scale=[1.0, -1.0, 1.0]), static=True)
        log("field/lines", rr.LineStrips2D(np.array(self.field.segments), colors=[(230, 230, 230)],
                                           radii=self.field.dims.line_width / 2), static=True)
        cx, cy, radius = self.field.center_circle
        angles = np.linspace(0.0, 2.0 * math.pi, 97)
        circle = np.stack([cx + radius * np.cos(angles), cy + radius * np.sin(angles)], axis=1)
        log("field/center_circle", rr.LineStrips2D([circle], colors=[(230, 230, 230)],
                                                   radii=self.field.dims.line_width / 2), static=True)
        hl, hw, border = self.field.half_length, self.field.half_width, self.field.dims.border_strip_width
        carpet = np.array([[-hl - border, -hw - border], [hl + border, -hw - border], [hl + border, hw + border],
                           [-hl - border, hw + border], [-hl - border, -hw - border]])
        log("field/carpet", rr.LineStrips2D([carpet], colors=[(20, 110, 40)], radii=0.02), static=True)
        for kind in LandmarkType:
            points = np.array(self.field.landmarks_of(kind))
            if points.shape[0]:
                log(f"field/landmarks/{kind.name.lower()}",
                    rr.Points2D(points, colors=[LANDMARK_COLORS[kind]], radii=0.06), static=True)
        for path, name, color in (("entropy/position", "position", (80, 160, 255)),
                                  ("entropy/orientation", "orientation", (255, 140, 40)),
                                  ("error/position", "position [m]", (80, 220, 120)),
                                  ("error/heading", "heading [rad]", (230, 80, 80))):
            log(path, rr.SeriesLines(names=name, colors=[color]), static=True)

    def set_time(self, step: int, t: float) -> None:
        """The step (an integer within [0, 2⁶²]) and time [s] what follows is logged at."""
        self._step, self._time = _step_and_time(step, t)
        self.stream.set_time("step", sequence=self._step)
        self.stream.set_time("time", duration=self._time)

    def log_scalars(self, values: dict[str, float]) -> None:
        """Log scalar series at the current time, e.g. {"proprioception/s_rel": 0.8} (buffered). Each value
        must be a finite number, each key a string; checked before any is logged."""
        if not isinstance(values, dict):
            raise ArgumentTypeError(f"values = {values!r} must be a dict of entity path to number")
        checked = [(path, real(f"values[{path!r}]", value)) for path, value in values.items()]
        for path, _ in checked:
            if not isinstance(path, str) or not path:
                raise ArgumentTypeError(f"values has the key {path!r}; entity paths are non-empty strings")
        for path, value in checked:
            self._scalar(path, value)

    def log_step(self, step: int, t: float, pf, truth=None, observations: Observations | None = None,
                 entropy=None) -> None:
        """Log one filter step: entropy and pose every step, particles every `particles_every` steps (buffered,
        see the module's docstring)."""
        step, t = _step_and_time(step, t)
        if truth is not None:
            truth = reals("truth", truth, 3)
        if observations is not None and not isinstance(observations, Observations):
            raise ArgumentTypeError(f"observations = {observations!r} must be an Observations or None")
        if self._buffered_steps >= self.flush_every or self._buffered_points >= self.max_points:
            self.flush()
        self._buffered_steps += 1
        self.set_time(step, t)
        entropy = entropy or pf.entropy()
        self._scalar("entropy/position", entropy.position)
        self._scalar("entropy/orientation", entropy.orientation)
        x, y, theta = map(float, pf.estimate().pose)
        self._arrow("robot/estimate", (x, y, theta))
        if truth is not None:
            tx, ty, ttheta = map(float, truth)
            self._arrow("robot/truth", (tx, ty, ttheta))
            self._scalar("error/position", float(np.hypot(x - tx, y - ty)))
            self._scalar("error/heading", abs(math.remainder(theta - ttheta, 2.0 * math.pi)))
        if step % self.particles_every == 0:
            positions = pf.poses[:, :2].astype(np.float32)      # a copy, as Rerun stores positions
            self._particles.append((self._step, self._time, positions, weight_colors(pf.weights)))
            self._buffered_points += positions.shape[0]
        if observations is not None and len(observations):
            # The arrows are computed for all the buffered steps when they are sent (`_ray_columns`): at robot
            # sizes, numpy's calls on one step's few detections cost more than their elements. The batch's
            # arrays are its own and read-only: kept as they are.
            self._rays.append((self._step, self._time, observations.ranges, observations.bearings,
                               observations.kinds, (x, y, math.cos(theta), math.sin(theta))))
