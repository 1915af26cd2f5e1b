"""Recording a filter run to Rerun (.rrd) for review in the Rerun viewer (see docs/recording.md).

    from mcl.tools.recording import Recorder
    with Recorder("walk.rrd", field, particles_every=5) as rec:
        for step, t in ...:
            ...
            rec.log_step(step, t, pf, truth=true_pose, observations=obs)
            if kidnapped:
                rec.log_event("kidnap", "carried 3 m", level="WARN")

Entity paths: `field/...` (static: lines, centre circle, landmarks by type), `particles` (every k-th step,
coloured by weight) with `particles/headings` (a short arrow along the heading of up to `max_headings` of
them), `robot/estimate`, `robot/truth`, `robot/uncertainty/particles` and `robot/uncertainty/estimate` (the 95 %
ellipses of the particle set's weighted position covariance and of the estimate's, at the particle steps),
`observations` (arrows from the estimate to each detection), `entropy/position`, `entropy/orientation` (every
step), `error/position`, `error/heading` (when the truth is known), `events` (a text log of `log_event` and
`log_change`, with a mark per event on `events/marks/<kind>` that the plots show); timelines `step`
(sequence), `time` (duration, seconds) and, when the recorder is given the log's origin (`origin_ns`), `LOG_TIMELINE`
(a timestamp: the origin plus the time), the timeline Rerun's MCAP import puts ROS 2 header stamps on. Anything
else (a model's state belief, a percept) goes through `log_scalars`. The file opens on a blueprint with the field
view beside the entropy and error plots and the event log. Data are logged in the field frame, in metres. Rerun's
2-D view draws +y downwards (the image convention), so each top-level entity carries a static y-flip transform
and the field appears as seen from above (+x right, +y up); the viewer's hover readout is in the view's
coordinates (y negated), its selection panel shows the logged field-frame values.

Logged arrays are fresh copies (or a detection batch's own read-only arrays): Rerun keeps a reference until it
flushes. `close()` (or the `with` block) writes the file's footer and then, for a file, compacts it (`compact`:
the chunks of each entity merged up to about 2 MiB, Rerun's object-store profile, as `rerun rrd optimize`
does; the figures in docs/recording.md). Everything a step logs is buffered and sent
as columns every `flush_every` steps (sooner when the buffered particles reach `max_points`): one
`send_columns` call costs what one `log` call does. The per-step series (entropy, errors, the
pose arrows, `log_scalars`) are one row per step; the particles, their headings, the ellipses and the detection
rays, whose lengths change from step to step, are partitioned columns (a row of N points, a row of as many rays
as detections). Logged call by call, most of a step's cost was its `log` calls. What remains per step is kept small: the particles' colours come from one
compiled pass (`weight_colors`), and the detection arrows are computed for all the buffered steps at once when
they are sent (`robocup-mcl bench` measures the recording phase; docs/recording.md).
"""

from __future__ import annotations

import math
import os
import re
import uuid
from collections.abc import Sequence
from functools import partial
from pathlib import Path
from typing import TYPE_CHECKING

import numba
import numpy as np
import rerun as rr
import rerun.blueprint as rrb
import rerun.chunk as rrc
from numpy.typing import ArrayLike

from field import Field, LandmarkType
from field.checks import ArgumentTypeError, integer, real, reals
from field.moved import moved_names
from mcl import reference as twins
from sensing.observations import Observations

if TYPE_CHECKING:
    from mcl.filter import ParticleFilter
    from mcl.summary import Entropy

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
# Radii: positive in metres, negative in the viewer's UI points (the same size at any zoom).
PARTICLE_RADIUS = -2.5  # UI points: a dot that reads at whole-field zoom (about 0.05 m there) and in close-ups
HEADING_LENGTH = 0.15  # m: a particle's heading arrow
HEADING_RADIUS = -0.75
HEADING_COLOR = (235, 235, 235, 160)
RAY_RADIUS = 0.01
ARROW_RADIUS = 0.03  # the estimate's and the truth's arrows
ELLIPSE_CHI2 = -2.0 * math.log(0.05)  # the 95 % quantile of χ² with 2 degrees of freedom (5.991)
ELLIPSE_VERTICES = 33  # a closed strip: the first vertex repeated at the end
ELLIPSE_RADIUS = -1.5
ELLIPSE_COLORS = {
    "robot/uncertainty/particles": (120, 200, 255, 255),
    "robot/uncertainty/estimate": (255, 110, 110, 255),
}
LOG_TIMELINE = "ros2_timestamp"  # Rerun's MCAP import puts ROS 2 header stamps on this timeline
EVENT_LEVELS = {
    "TRACE": (150, 150, 150),
    "DEBUG": (150, 150, 150),
    "INFO": (120, 200, 255),
    "WARN": (255, 170, 40),
    "ERROR": (255, 60, 60),
    "CRITICAL": (255, 0, 200),
}
EVENT_KIND = re.compile(r"^[a-z0-9_]+$")


__getattr__ = moved_names(
    __name__,
    {
        "weight_colors_reference": (
            "weight_colors(weights, reference=True)",
            lambda: partial(weight_colors, reference=True),
        )
    },
)

_LOW = np.array([40.0, 30.0, 120.0])  # the lightest particle's colour (dark blue)
_HIGH = np.array([255.0, 230.0, 40.0])  # the heaviest's (yellow)


def weight_colors(weights: np.ndarray, *, reference: bool = False) -> np.ndarray:
    """Map weights to RGB (N, 3) uint8 from dark blue (lightest) to yellow (heaviest), relative to the heaviest
    (all dark blue when the heaviest is not positive). One pass in compiled code (its numpy twin
    `mcl.reference.weight_colors`, bit for bit): numpy's half a dozen passes and (N, 3) temporaries cost more than the rest of a step's
    recording at N >= 10 000, and their calls more than the particles at N = 100.

    Parameters
    ----------
    weights : np.ndarray
        (N,) particle weights (any scale: only their ratio to the heaviest counts).
    reference : bool, default False
        Compute them with the numpy twin instead (for tests).

    Returns
    -------
    np.ndarray
        (N, 3) uint8 RGB colours.
    """
    weights = np.ascontiguousarray(weights, dtype=np.float64)
    if reference:
        return twins.weight_colors(weights, _LOW, _HIGH)
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
            if w > top or w != w:  # np.max: the largest, NaN if there is one
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
        level = 0.0 if level < 0.0 else level  # np.clip (a NaN stays NaN)
        level = 1.0 if level > 1.0 else level
        out[i, 0] = np.uint8(low[0] + level * d0)
        out[i, 1] = np.uint8(low[1] + level * d1)
        out[i, 2] = np.uint8(low[2] + level * d2)


def weighted_position_covariance(poses: np.ndarray, weights: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The weighted mean (2,) and covariance (2, 2) of the particles' positions (weights normalised here; the
    covariance with weights as frequencies, Σ wᵢ (pᵢ − μ)(pᵢ − μ)ᵀ, numpy's `cov(..., aweights=w, bias=True)`).
    Uniform weights when they do not sum to a positive number.

    Parameters
    ----------
    poses : np.ndarray
        (N, 3) particle poses (x [m], y [m], θ [rad]); only the positions are used.
    weights : np.ndarray
        (N,) particle weights, normalised here.

    Returns
    -------
    mean : np.ndarray
        (2,) float64 weighted mean position [m].
    covariance : np.ndarray
        (2, 2) float64 weighted covariance of the positions [m²].
    """
    xy = np.asarray(poses, dtype=np.float64)[:, :2]
    w = np.asarray(weights, dtype=np.float64)
    total = float(w.sum())
    w = w / total if total > 0.0 and math.isfinite(total) else np.full(xy.shape[0], 1.0 / max(xy.shape[0], 1))
    mean = w @ xy
    d = xy - mean
    return mean, (d * w[:, None]).T @ d


def covariance_ellipse(
    mean: ArrayLike, covariance: ArrayLike, chi2: float = ELLIPSE_CHI2, vertices: int = ELLIPSE_VERTICES
) -> np.ndarray:
    """The closed outline (vertices, 2) of {p : (p − mean)ᵀ covariance⁻¹ (p − mean) = chi2} (by default the 95 %
    ellipse of a 2-D normal); a degenerate covariance gives a segment or a point, a non-finite one NaNs.

    Parameters
    ----------
    mean : array_like
        The centre (x, y) [m]; only its first two entries are used (a pose (x, y, θ) will do).
    covariance : array_like
        The position covariance [m²]; only its upper-left 2 × 2 block is used (a pose covariance will do).
        Symmetrised; negative eigenvalues count as zero.
    chi2 : float, optional
        The squared Mahalanobis distance of the outline; default `ELLIPSE_CHI2` (5.991, the 95 % quantile of χ²
        with 2 degrees of freedom).
    vertices : int, optional
        Number of vertices, the first repeated as the last; default `ELLIPSE_VERTICES` (33).

    Returns
    -------
    np.ndarray
        (vertices, 2) float64 outline [m]; all NaN when the mean or the covariance is not finite.
    """
    mean = np.asarray(mean, dtype=np.float64)[:2]
    covariance = np.asarray(covariance, dtype=np.float64)[:2, :2]
    if not np.isfinite(covariance).all() or not np.isfinite(mean).all():
        return np.full((vertices, 2), np.nan)
    values, vectors = np.linalg.eigh(0.5 * (covariance + covariance.T))
    axes = vectors * np.sqrt(chi2 * np.clip(values, 0.0, None))  # columns: the semi-axes
    angles = np.linspace(0.0, 2.0 * math.pi, vertices)
    outline = mean + np.stack([np.cos(angles), np.sin(angles)], axis=1) @ axes.T
    outline[-1] = outline[0]
    return outline


def default_blueprint(
    series: tuple[tuple[str, str], ...] = (("/entropy", "entropy [bits]"), ("/error", "error [m, rad]")),
    field_bounds: tuple[tuple[float, float], tuple[float, float]] | None = None,
    time_panel: rrb.TimePanel | None = None,
) -> rrb.Blueprint:
    """The field view beside a column of time-series plots, one per (entity origin, title) in `series`, each
    with the event marks (`/events/marks/**`), above the event log (`/events`). field_bounds: what the field view
    shows, ((x_min, x_max), (y_min, y_max)) in the field frame (default: all of it); time_panel: e.g. the
    timeline and play state the viewer opens on.

    Parameters
    ----------
    series : tuple of (str, str), optional
        (entity origin, title) of each time-series plot, top to bottom; default the entropy ("/entropy") and
        the errors ("/error").
    field_bounds : tuple of (float, float) or None, optional
        ((x_min, x_max), (y_min, y_max)) [m] the field view shows, in the field frame; None (the default): all
        of it.
    time_panel : rrb.TimePanel or None, optional
        The time panel's state (e.g. the timeline and play state the viewer opens on); None (the default):
        Rerun's.

    Returns
    -------
    rrb.Blueprint
        The blueprint, its side panels collapsed.
    """
    bounds = None
    if field_bounds is not None:
        (x0, x1), (y0, y1) = field_bounds
        bounds = rrb.VisualBounds2D(x_range=[x0, x1], y_range=[-y1, -y0])  # the view's y is the field's -y
    return rrb.Blueprint(
        rrb.Horizontal(
            rrb.Spatial2DView(
                origin="/",
                name="field",
                visual_bounds=bounds,
                contents=["/field/**", "/particles/**", "/robot/**", "/observations"],
            ),
            rrb.Vertical(
                *(
                    rrb.TimeSeriesView(origin=origin, name=name, contents=[f"{origin}/**", "/events/marks/**"])
                    for origin, name in series
                ),
                rrb.TextLogView(origin="/events", name="events"),
                row_shares=[3] * len(series) + [2],
            ),
            column_shares=[3, 2],
        ),
        *(() if time_panel is None else (time_panel,)),
        collapse_panels=True,
    )


def compact_file(
    path: str | Path,
    blueprint: rrb.Blueprint | None = None,
    profile: rrc.OptimizationProfile = rrc.OptimizationProfile.OBJECT_STORE,
) -> None:
    """Rewrite the .rrd file at `path` with its recording's chunks merged (`profile`, by default Rerun's
    object-store profile: chunks up to about 2 MiB, as `rerun rrd optimize` makes them), keeping its application
    and recording ids, with `blueprint` as the default blueprint (None: the file's blueprint is not kept). The new
    file replaces the old one only once it is complete.

    Parameters
    ----------
    path : str or Path
        The .rrd file, rewritten in place (its first recording is kept).
    blueprint : rrb.Blueprint or None, optional
        The default blueprint of the new file; None (the default) writes none.
    profile : rrc.OptimizationProfile, optional
        How the chunks are merged; default `rrc.OptimizationProfile.OBJECT_STORE`.
    """
    path = Path(path)
    reader = rrc.RrdReader(str(path))
    entry = reader.recordings()[0]
    store = reader.stream(store=entry).collect(optimize=profile)
    scratch = path.with_name(path.name + ".compacting")
    out = rr.RecordingStream(entry.application_id, recording_id=entry.recording_id, send_properties=False)
    try:
        out.save(str(scratch), default_blueprint=blueprint)
        rr.send_chunks(store, recording=out)
        out.disconnect()
        os.replace(scratch, path)
    finally:
        if scratch.exists():
            scratch.unlink()


def _step_and_time(step, t) -> tuple[int, float]:
    return integer("step", step, 0, 2**62), real("t", t)


class Recorder:
    """Writes one filter run to an .rrd file (or to any `rr.RecordingStream` you pass).

    Parameters
    ----------
    path : str or Path or None
        The .rrd file to write (its folder is created); None to log only to `stream`.
    field : Field
        The field, drawn once as static entities (`field/...`).
    particles_every : int, optional
        Log the particles, their headings and the uncertainty ellipses every this many steps (the steps whose
        number is a multiple of it), >= 1; default 5.
    application_id : str, optional
        Rerun's application id of the stream the recorder makes; default "robocup-mcl".
    stream : rr.RecordingStream or None, optional
        Log to this stream instead of a new one (with a `path`, the stream is saved there); None (the default)
        makes one.
    blueprint : rrb.Blueprint or None, optional
        The file's default blueprint; None (the default) for `default_blueprint()`.
    flush_every : int, optional
        Send the buffered rows as columns every this many steps, >= 1; default 200.
    max_points : int, optional
        Send sooner when the buffered particles and heading arrows reach this many, >= 1; default 1 000 000.
    max_headings : int, optional
        At most this many particles get a heading arrow per logged step (every ⌈N / max_headings⌉-th), >= 1;
        default 100.
    recording_id : str or None, optional
        The recording's id (default: a fresh one per recorder); a converted MCAP log given the same id
        (`rerun mcap convert --recording-id`) opens as one recording with this one.
    origin_ns : int or None, optional
        What t = 0 is, in ns since the Unix epoch (a replayed log's `origin_ns`); given, every row is also on
        the `LOG_TIMELINE` timestamp. None (the default): no such timeline.
    compact : bool, optional
        Compact the file when closing (`compact_file`; only for a path, not a stream you pass); default True.

    Raises
    ------
    ValueError
        If a count is not an integer >= 1, `origin_ns` is outside int64, or neither `path` nor `stream` is
        given; TypeError (`field.checks.ArgumentTypeError`) if `origin_ns` is not an integer.
    """

    def __init__(
        self,
        path: str | Path | None,
        field: Field,
        particles_every: int = 5,
        application_id: str = "robocup-mcl",
        stream: rr.RecordingStream | None = None,
        blueprint: rrb.Blueprint | None = None,
        flush_every: int = 200,
        max_points: int = 1_000_000,
        max_headings: int = 100,
        recording_id: str | None = None,
        origin_ns: int | None = None,
        compact: bool = True,
    ) -> None:
        for name, value in (
            ("particles_every", particles_every),
            ("flush_every", flush_every),
            ("max_points", max_points),
            ("max_headings", max_headings),
        ):
            if isinstance(value, bool) or not isinstance(value, int) or value < 1:
                raise ValueError(f"{name} = {value!r} must be an integer >= 1")
        self.origin_ns = None if origin_ns is None else integer("origin_ns", origin_ns, -(2**63), 2**63 - 1)
        self.flush_every = flush_every
        self.max_points = max_points
        self.max_headings = max_headings
        self.compact = bool(compact)
        self._step, self._time = 0, 0.0
        self._scalars: dict[str, list[tuple[int, float, float]]] = {}
        self._arrows: dict[str, list[tuple[int, float, float, float, float, float]]] = {}
        # Rows of varying length: (step, time, arrays of one row each), sent as partitioned columns.
        self._particles: list[tuple[int, float, np.ndarray, np.ndarray]] = []
        self._headings: list[tuple[int, float, np.ndarray, np.ndarray]] = []
        self._ellipses: dict[str, list[tuple[int, float, np.ndarray]]] = {}
        self._rays: list[tuple[int, float, np.ndarray, np.ndarray, np.ndarray, tuple]] = []
        self._events: list[tuple[int, float, str, str, str]] = []
        self._event_kinds: set[str] = set()
        self._last: dict[str, object] = {}  # `log_change`'s last value per kind
        self._last_injected = 0
        self._buffered_points = 0
        self._buffered_steps = 0
        if stream is None and path is None:
            raise ValueError("give a path or a stream")
        self.field = field
        self.particles_every = particles_every
        self.path = None if path is None else Path(path)
        self.blueprint = blueprint or default_blueprint()
        self.stream = stream or rr.RecordingStream(application_id, recording_id=recording_id or str(uuid.uuid4()))
        self.recording_id = self.stream.get_recording_id()
        if self.path is not None:
            self.path.parent.mkdir(parents=True, exist_ok=True)
            self.stream.save(str(self.path), default_blueprint=self.blueprint)
        self._log_field()

    def __enter__(self) -> Recorder:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def close(self) -> None:
        """Send what is buffered, flush and write the footer; then compact the file (`compact`)."""
        self.flush()
        self.stream.disconnect()
        if self.path is not None and self.compact:
            compact_file(self.path, self.blueprint)

    def flush(self) -> None:
        """Send what is buffered (the series, the particles and the detection arrows) as columns."""
        for path, rows in self._scalars.items():
            if rows:
                steps, times, values = (np.array(column) for column in zip(*rows))
                self.stream.send_columns(
                    path, indexes=self._indexes(steps, times), columns=rr.Scalars.columns(scalars=values)
                )
        for path, arrow_rows in self._arrows.items():
            if arrow_rows:
                table = np.array(arrow_rows)  # colours and radii: static (`_log_field`)
                self.stream.send_columns(
                    path,
                    indexes=self._indexes(table[:, 0].astype(np.int64), table[:, 1]),
                    columns=rr.Arrows2D.columns(origins=table[:, 2:4], vectors=table[:, 4:6]),
                )
        if self._particles:
            self._send_rows(
                "particles",
                self._particles,
                lambda lengths, positions, colors: rr.Points2D.columns(positions=positions, colors=colors),
            )
        if self._headings:
            self._send_rows(
                "particles/headings",
                self._headings,
                lambda lengths, origins, vectors: rr.Arrows2D.columns(origins=origins, vectors=vectors),
            )
        for path, ellipse_rows in self._ellipses.items():
            if ellipse_rows:
                at_steps, at_times, outlines = zip(*ellipse_rows)
                self.stream.send_columns(
                    path,
                    indexes=self._indexes(np.array(at_steps), np.array(at_times)),
                    columns=rr.LineStrips2D.columns(strips=np.stack(outlines)).partition(
                        np.ones(len(outlines), dtype=np.int64)
                    ),
                )
        if self._rays:
            self._send_rows("observations", self._rays, self._ray_columns)
        if self._events:
            self._send_events()
        self._scalars = {}
        self._arrows = {}
        self._particles = []
        self._headings = []
        self._ellipses = {}
        self._rays = []
        self._events = []
        self._buffered_points = 0
        self._buffered_steps = 0

    def _send_events(self) -> None:
        """The buffered events as one text-log column on `events` and one mark column per kind."""
        steps, times, kinds, texts, levels = (np.array(column) for column in zip(*self._events))
        self.stream.send_columns(
            "events",
            indexes=self._indexes(steps, times),
            columns=rr.TextLog.columns(
                text=[f"{kind}: {text}" for kind, text in zip(kinds, texts)], level=list(levels)
            ),
        )
        for kind in dict.fromkeys(kinds):
            rows = kinds == kind
            self.stream.send_columns(
                f"events/marks/{kind}",
                indexes=self._indexes(steps[rows], times[rows]),
                columns=rr.Scalars.columns(scalars=np.zeros(int(rows.sum()))),
            )

    def _send_rows(self, path: str, rows: list, columns) -> None:
        """Rows (step, time, arrays of that step's entries[, a tuple of that step's values]) as one send of
        partitioned columns: columns(row lengths, *arrays concatenated over the rows[, the tuples as an array
        of one row per step]) makes them. The radii (and colours shared by all) are static (`_log_field`)."""
        steps, times, *arrays = zip(*rows)
        lengths = [entries.shape[0] for entries in arrays[0]]
        batch = columns(
            lengths, *(np.array(parts) if isinstance(parts[0], tuple) else np.concatenate(parts) for parts in arrays)
        )
        self.stream.send_columns(
            path, indexes=self._indexes(np.array(steps), np.array(times)), columns=batch.partition(lengths)
        )

    @staticmethod
    def _ray_columns(lengths, ranges, bearings, kinds, estimates):
        """The detection arrows of buffered rows: from the estimate at each row's step (`estimates`, one
        (x, y, cos θ, sin θ) per row) to each detection, in the field frame."""
        px, py = ranges * np.cos(bearings), ranges * np.sin(bearings)  # `Observations.points`
        frames = np.repeat(estimates, lengths, axis=0)
        c, s = frames[:, 2], frames[:, 3]
        vectors = np.stack([c * px - s * py, s * px + c * py], axis=1)
        return rr.Arrows2D.columns(origins=frames[:, :2], vectors=vectors, colors=LANDMARK_PALETTE[kinds])

    def _indexes(self, steps: np.ndarray, times: np.ndarray) -> list:
        """The time columns of rows at `steps` and `times` [s]: `step`, `time` and, with an origin, the
        `LOG_TIMELINE` timestamp."""
        indexes = [rr.TimeColumn("step", sequence=steps), rr.TimeColumn("time", duration=times)]
        if self.origin_ns is not None:
            stamps = self.origin_ns + np.round(np.asarray(times, dtype=np.float64) * 1e9).astype(np.int64)
            indexes.append(rr.TimeColumn(LOG_TIMELINE, timestamp=stamps.astype("datetime64[ns]")))
        return indexes

    def _ellipse(self, path: str, outline: np.ndarray) -> None:
        self._ellipses.setdefault(path, []).append((self._step, self._time, outline.astype(np.float32)))

    def _scalar(self, path: str, value: float) -> None:
        self._scalars.setdefault(path, []).append((self._step, self._time, float(value)))

    def _arrow(self, path: str, pose: tuple[float, float, float]) -> None:
        self._arrows.setdefault(path, []).append(
            (self._step, self._time, float(pose[0]), float(pose[1]), 0.35 * math.cos(pose[2]), 0.35 * math.sin(pose[2]))
        )

    def _log_field(self) -> None:
        log = self.stream.log
        for root in ("field", "particles", "robot", "observations"):
            log(root, rr.Transform3D(scale=[1.0, -1.0, 1.0]), static=True)
        log(
            "field/lines",
            rr.LineStrips2D(
                np.array(self.field.segments), colors=[(230, 230, 230)], radii=self.field.dims.line_width / 2
            ),
            static=True,
        )
        cx, cy, radius = self.field.center_circle
        angles = np.linspace(0.0, 2.0 * math.pi, 97)
        circle = np.stack([cx + radius * np.cos(angles), cy + radius * np.sin(angles)], axis=1)
        log(
            "field/center_circle",
            rr.LineStrips2D([circle], colors=[(230, 230, 230)], radii=self.field.dims.line_width / 2),
            static=True,
        )
        x_min, x_max, y_min, y_max = self.field.carpet
        carpet = np.array([[x_min, y_min], [x_max, y_min], [x_max, y_max], [x_min, y_max], [x_min, y_min]])
        log("field/carpet", rr.LineStrips2D([carpet], colors=[(20, 110, 40)], radii=0.02), static=True)
        for kind in LandmarkType:
            points = np.array(self.field.landmarks_of(kind))
            if points.shape[0]:
                log(
                    f"field/landmarks/{kind.name.lower()}",
                    rr.Points2D(points, colors=[LANDMARK_COLORS[kind]], radii=0.06),
                    static=True,
                )
        for path, name, color in (
            ("entropy/position", "position", (80, 160, 255)),
            ("entropy/orientation", "orientation", (255, 140, 40)),
            ("error/position", "position [m]", (80, 220, 120)),
            ("error/heading", "heading [rad]", (230, 80, 80)),
        ):
            log(path, rr.SeriesLines(names=name, colors=[color]), static=True)
        log("particles", rr.Points2D.from_fields(radii=PARTICLE_RADIUS), static=True)
        log("particles/headings", rr.Arrows2D.from_fields(colors=[HEADING_COLOR], radii=HEADING_RADIUS), static=True)
        log("observations", rr.Arrows2D.from_fields(radii=RAY_RADIUS), static=True)
        for path, color in ARROW_COLORS.items():
            log(path, rr.Arrows2D.from_fields(colors=[color], radii=ARROW_RADIUS), static=True)
        for path, ellipse_color in ELLIPSE_COLORS.items():
            log(path, rr.LineStrips2D.from_fields(colors=[ellipse_color], radii=ELLIPSE_RADIUS), static=True)

    def set_time(self, step: int, t: float) -> None:
        """The step (an integer within [0, 2⁶²]) and time [s] what follows is logged at (and, with an origin,
        the `LOG_TIMELINE` timestamp).

        Parameters
        ----------
        step : int
            The step number, within [0, 2⁶²].
        t : float
            The time [s] since the run's start (or since `origin_ns`), finite.

        Raises
        ------
        ValueError
            If `step` is out of range or `t` is not finite; TypeError (`field.checks.ArgumentTypeError`) if
            either is not a number of its kind.
        """
        self._step, self._time = _step_and_time(step, t)
        self.stream.set_time("step", sequence=self._step)
        self.stream.set_time("time", duration=self._time)
        if self.origin_ns is not None:
            self.stream.set_time(
                LOG_TIMELINE, timestamp=np.datetime64(self.origin_ns + int(round(self._time * 1e9)), "ns")
            )

    def log_event(self, kind: str, text: str, level: str = "INFO") -> None:
        """Log an event at the current time (buffered): a `TextLog` line "kind: text" with `level` (TRACE, DEBUG,
        INFO, WARN, ERROR or CRITICAL) on `events`, and a mark at 0 on `events/marks/<kind>`, which the default
        blueprint's plots show. `kind`: lower-case letters, digits and underscores (e.g. "kidnap", "quality").

        Parameters
        ----------
        kind : str
            The event's kind: lower-case letters, digits and underscores.
        text : str
            The event's text.
        level : str, optional
            The text log's level: a key of `EVENT_LEVELS` (TRACE, DEBUG, INFO, WARN, ERROR, CRITICAL); default
            "INFO". The first event of a kind sets its mark's colour.

        Raises
        ------
        TypeError
            (`field.checks.ArgumentTypeError`) If `kind`, `text` or `level` is not as above.
        """
        if not isinstance(kind, str) or not EVENT_KIND.match(kind):
            raise ArgumentTypeError(f"kind = {kind!r} must be lower-case letters, digits and underscores")
        if not isinstance(text, str):
            raise ArgumentTypeError(f"text = {text!r} must be a string")
        if level not in EVENT_LEVELS:
            raise ArgumentTypeError(f"level = {level!r} must be one of {tuple(EVENT_LEVELS)}")
        if kind not in self._event_kinds:
            self._event_kinds.add(kind)
            self.stream.log(
                f"events/marks/{kind}",
                rr.SeriesPoints(names=kind, colors=[EVENT_LEVELS[level]], markers="diamond", marker_sizes=6.0),
                static=True,
            )
        self._events.append((self._step, self._time, kind, text, level))

    def log_change(
        self, kind: str, value: object, text: str | None = None, level: str = "INFO", initial: bool = True
    ) -> bool:
        """Log an event (`log_event`) when `value` differs from the value last given for `kind` (the first value
        too, unless `initial` is False): e.g. log_change("quality", localizer.quality().value) each step marks
        each change of quality. `text` defaults to str(value). Returns whether an event was logged.

        Parameters
        ----------
        kind : str
            The event's kind, as `log_event`.
        value : object
            The value to compare (with ==) with the last one given for `kind`.
        text : str or None, optional
            The event's text; None (the default) for str(value).
        level : str, optional
            As `log_event`; default "INFO".
        initial : bool, optional
            Whether the first value given for `kind` logs an event (default True).

        Returns
        -------
        bool
            True when an event was logged.

        Raises
        ------
        TypeError
            (`field.checks.ArgumentTypeError`) As `log_event`, when an event is logged.
        """
        first = kind not in self._last
        if not first and self._last[kind] == value:
            return False
        self._last[kind] = value
        if first and not initial:
            return False
        self.log_event(kind, str(value) if text is None else text, level)
        return True

    def log_scalars(self, values: dict[str, float]) -> None:
        """Log scalar series at the current time, e.g. {"proprioception/s_rel": 0.8} (buffered). Each value
        must be a finite number, each key a string; checked before any is logged.

        Parameters
        ----------
        values : dict of str to float
            Entity path (non-empty) to value.

        Raises
        ------
        ValueError
            If a value is not finite; TypeError (`field.checks.ArgumentTypeError`) if `values` is not a dict, a
            value not a number or a key not a non-empty string.
        """
        if not isinstance(values, dict):
            raise ArgumentTypeError(f"values = {values!r} must be a dict of entity path to number")
        checked = [(path, real(f"values[{path!r}]", value)) for path, value in values.items()]
        for path, _ in checked:
            if not isinstance(path, str) or not path:
                raise ArgumentTypeError(f"values has the key {path!r}; entity paths are non-empty strings")
        for path, value in checked:
            self._scalar(path, value)

    def log_step(
        self,
        step: int,
        t: float,
        pf: ParticleFilter,
        truth: Sequence[float] | np.ndarray | None = None,
        observations: Observations | None = None,
        entropy: Entropy | None = None,
    ) -> None:
        """Log one filter step: entropy and pose every step; the particles, their headings and the uncertainty
        ellipses every `particles_every` steps (buffered, see the module's docstring). When the filter's last
        correction injected particles (augmented MCL's sensor resetting, `pf.injected`) and the one before had
        not, an event "reset" is logged.

        Parameters
        ----------
        step : int
            The step number, within [0, 2⁶²] (see `set_time`).
        t : float
            The time [s], finite (see `set_time`).
        pf : ParticleFilter
            The filter (or anything with its `poses`, `weights`, `estimate()` and `entropy()`, and optionally
            `injected`).
        truth : sequence of float or np.ndarray or None, optional
            The true pose (x [m], y [m], θ [rad]): logged with the position and heading errors; None (the
            default) when unknown.
        observations : Observations or None, optional
            The step's detections, drawn as arrows from the estimate; None (the default) for none.
        entropy : Entropy or None, optional
            The belief's entropy when already computed; None (the default) asks `pf.entropy()`.

        Raises
        ------
        ValueError
            If `step`, `t` or `truth` is out of range or not finite; TypeError (`field.checks.ArgumentTypeError`)
            if one of them is not a number (or three) or `observations` is not an `Observations`.
        """
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
        estimate = pf.estimate()
        x, y, theta = map(float, estimate.pose)
        self._arrow("robot/estimate", (x, y, theta))
        if truth is not None:
            tx, ty, ttheta = map(float, truth)
            self._arrow("robot/truth", (tx, ty, ttheta))
            self._scalar("error/position", float(np.hypot(x - tx, y - ty)))
            self._scalar("error/heading", abs(math.remainder(theta - ttheta, 2.0 * math.pi)))
        if step % self.particles_every == 0:
            poses, weights = pf.poses, pf.weights
            positions = poses[:, :2].astype(np.float32)  # a copy, as Rerun stores positions
            self._particles.append((self._step, self._time, positions, weight_colors(weights)))
            stride = -(-poses.shape[0] // self.max_headings)
            headings = poses[::stride, 2]
            self._headings.append(
                (
                    self._step,
                    self._time,
                    positions[::stride],
                    (HEADING_LENGTH * np.stack([np.cos(headings), np.sin(headings)], axis=1)).astype(np.float32),
                )
            )
            self._buffered_points += positions.shape[0] + headings.shape[0]
            mean, covariance = weighted_position_covariance(poses, weights)
            self._ellipse("robot/uncertainty/particles", covariance_ellipse(mean, covariance))
            self._ellipse("robot/uncertainty/estimate", covariance_ellipse(estimate.pose, estimate.covariance))
        injected = int(getattr(pf, "injected", 0) or 0)
        if injected > 0 and self._last_injected == 0:
            self.log_event("reset", f"sensor resetting: {injected} of {pf.poses.shape[0]} particles injected")
        self._last_injected = injected
        if observations is not None and len(observations):
            # The arrows are computed for all the buffered steps when they are sent (`_ray_columns`): at robot
            # sizes, numpy's calls on one step's few detections cost more than their elements. The batch's
            # arrays are its own and read-only: kept as they are.
            self._rays.append(
                (
                    self._step,
                    self._time,
                    observations.ranges,
                    observations.bearings,
                    observations.kinds,
                    (x, y, math.cos(theta), math.sin(theta)),
                )
            )
