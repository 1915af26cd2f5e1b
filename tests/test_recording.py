"""The recording: what `Recorder.log_step` buffers is what the .rrd file holds, row by row."""

import math
import subprocess

import numpy as np
import pytest
import rerun.blueprint as rrb
import rerun.chunk as rrc
from hypothesis import given
from hypothesis import strategies as st

from benchmarks.recording_stats import rerun_command
from benchmarks.step import TRUE_POSE, bench_setup
from field import LandmarkType, spl
from field.checks import ArgumentTypeError
from mcl import Entropy, Estimate
from mcl.tools.recording import (
    ELLIPSE_CHI2,
    ELLIPSE_VERTICES,
    HEADING_LENGTH,
    LANDMARK_COLORS,
    LOG_TIMELINE,
    PARTICLE_RADIUS,
    Recorder,
    covariance_ellipse,
    default_blueprint,
    weight_colors,
    weighted_position_covariance,
)


def rows(path, entity, component):
    """{step: array} of one component of an entity's temporal rows, read back from the .rrd file."""
    found = {}
    for chunk in rrc.RrdReader(str(path)).stream():
        if chunk.entity_path != entity or chunk.is_static:
            continue
        batch = chunk.to_record_batch()
        names = batch.schema.names
        column = batch.column(names.index(next(n for n in names if n.endswith(":" + component))))
        for step, value in zip(batch.column(names.index("step")).to_pylist(), column.to_pylist()):
            assert step not in found, f"{entity}: step {step} logged twice"
            found[step] = np.array(value)
    return found


@pytest.mark.parametrize("flush_every, max_points", [(3, 120), (200, 1_000_000), (1, 1)])
def test_particles_and_rays_read_back_as_logged(tmp_path, flush_every, max_points):
    """Particles every second step and the detections' arrows every step, through flushes by step count and
    by buffered points: each row holds that step's particles (as float32), their weight colours, and one
    arrow per detection from the estimate, in the field frame."""
    pf, u, observations = bench_setup(50)
    path = tmp_path / "run.rrd"
    expected_particles, expected_colors, expected_origins, expected_vectors = {}, {}, {}, {}
    points = observations.points()
    with Recorder(path, pf.field, particles_every=2, flush_every=flush_every, max_points=max_points) as recorder:
        for step in range(7):
            estimate = pf.step(u, observations)
            recorder.log_step(step, 0.01 * step, pf, truth=TRUE_POSE, observations=observations)
            if step % 2 == 0:
                expected_particles[step] = pf.poses[:, :2].astype(np.float32)
                expected_colors[step] = weight_colors(pf.weights, reference=True)
            c, s = math.cos(estimate.theta), math.sin(estimate.theta)
            expected_origins[step] = np.tile(estimate.pose[:2], (len(observations), 1))
            expected_vectors[step] = points @ np.array([[c, s], [-s, c]])
    particles = rows(path, "/particles", "positions")
    assert sorted(particles) == [0, 2, 4, 6]
    for step, positions in particles.items():
        assert np.array_equal(positions, expected_particles[step])
    particle_colors = rows(path, "/particles", "colors")
    assert sorted(particle_colors) == [0, 2, 4, 6]
    for step, packed in particle_colors.items():
        r, g, b = (expected_colors[step][:, k].astype(np.int64) for k in range(3))
        assert np.array_equal(packed, r << 24 | g << 16 | b << 8 | 255)
    origins = rows(path, "/observations", "origins")
    vectors = rows(path, "/observations", "vectors")
    assert sorted(origins) == sorted(vectors) == list(range(7))
    for step in range(7):
        np.testing.assert_allclose(origins[step], expected_origins[step], rtol=1e-6, atol=1e-6)
        np.testing.assert_allclose(vectors[step], expected_vectors[step], rtol=1e-6, atol=1e-6)
    colors = rows(path, "/observations", "colors")
    r, g, b = LANDMARK_COLORS[LandmarkType.GOALPOST]
    assert all((row == (r << 24 | g << 16 | b << 8 | 255)).all() for row in colors.values())


@given(st.lists(st.floats(0.0, 1e3), max_size=300), st.sampled_from(["as drawn", "zeros", "one NaN"]))
def test_weight_colors_are_their_numpy_twins(weights, case):
    """The compiled colours are their numpy twin's (`reference=True`), bit for bit: dark blue (lightest) to yellow
    (heaviest), all dark blue when no weight is positive."""
    weights = np.array(weights, dtype=np.float64)
    if case == "zeros":
        weights[:] = 0.0
    elif case == "one NaN" and weights.size:
        weights[weights.size // 2] = np.nan
    colors = weight_colors(weights)
    assert colors.dtype == np.uint8 and colors.shape == (weights.size, 3)
    assert np.array_equal(colors, weight_colors(weights, reference=True))
    if weights.size and weights.max() > 0:
        assert colors[int(np.argmax(weights))].tolist() == [255, 230, 40]
    else:
        assert (colors == [40, 30, 120]).all()


def test_a_step_without_detections_logs_no_arrows(tmp_path):
    pf, u, observations = bench_setup(20)
    path = tmp_path / "run.rrd"
    with Recorder(path, pf.field) as recorder:
        recorder.log_step(0, 0.0, pf, observations=observations)
        recorder.log_step(1, 0.01, pf, observations=None)
    assert sorted(rows(path, "/observations", "vectors")) == [0]
    assert sorted(rows(path, "/particles", "positions")) == [0]


@pytest.mark.parametrize("option", ["particles_every", "flush_every", "max_points"])
@pytest.mark.parametrize("value", [0, -1, 2.5, True])
def test_bad_options_are_rejected(tmp_path, option, value):
    pf, _, _ = bench_setup(10)
    with pytest.raises(ValueError, match=option):
        Recorder(tmp_path / "run.rrd", pf.field, **{option: value})


# ---------------------------------------------------------------------------------- review: uncertainty, events


class StandInFilter:
    """What `Recorder.log_step` reads of a filter, with chosen particles and weights."""

    def __init__(self, poses, weights, injected=0):
        self.poses, self.weights, self.injected = poses, weights, injected
        self.covariance = np.array([[0.04, 0.01, 0.0], [0.01, 0.09, 0.0], [0.0, 0.0, 0.01]])

    def estimate(self):
        return Estimate(self.poses[int(np.argmax(self.weights))].copy(), self.covariance, 0.9)

    def entropy(self):
        return Entropy(3.0, 2.0)


def skewed_particles(n=250, seed=3):
    """Particles in two clumps, the far one light: the weighted covariance is far from the unweighted one."""
    rng = np.random.default_rng(seed)
    poses = np.column_stack([rng.normal(0.0, 0.3, n), rng.normal(0.0, 0.5, n), rng.uniform(-np.pi, np.pi, n)])
    poses[: n // 5, :2] += (3.0, -2.0)
    weights = rng.uniform(0.5, 1.0, n)
    weights[: n // 5] *= 0.02
    return poses, weights / weights.sum()


def static_rows(path, entity, component):
    """The value of one component of an entity's static data, read back from the .rrd file."""
    for chunk in rrc.RrdReader(str(path)).stream():
        if chunk.entity_path == entity and chunk.is_static:
            batch = chunk.to_record_batch()
            names = [n for n in batch.schema.names if n.endswith(":" + component)]
            if names:
                return batch.column(batch.schema.names.index(names[0])).to_pylist()[0]
    return None


def test_the_ellipse_is_the_weighted_covariance_of_the_particles(tmp_path):
    """At each particle step, `robot/uncertainty/particles` is the 95 % ellipse of the particles' weighted
    position covariance (numpy's, with the weights as aweights): every vertex lies at Mahalanobis distance² χ²₂(95 %)
    = 5.991 from the weighted mean, the outline is closed and reaches the ends of both axes. The unweighted
    covariance does not fit it. `robot/uncertainty/estimate` is the estimate's covariance's ellipse."""
    poses, weights = skewed_particles()
    path = tmp_path / "run.rrd"
    with Recorder(path, spl(), particles_every=2) as recorder:
        for step in range(3):
            recorder.log_step(step, 0.01 * step, StandInFilter(poses, weights))
    outlines = rows(path, "/robot/uncertainty/particles", "strips")
    assert sorted(outlines) == [0, 2]
    mean = np.average(poses[:, :2], axis=0, weights=weights)
    covariance = np.cov(poses[:, :2].T, aweights=weights, bias=True)
    for outline in outlines.values():
        outline = outline.reshape(-1, 2).astype(np.float64)
        assert outline.shape == (ELLIPSE_VERTICES, 2) and np.allclose(outline[0], outline[-1])
        d = outline - mean
        distances = np.einsum("ij,jk,ik->i", d, np.linalg.inv(covariance), d)
        np.testing.assert_allclose(distances, ELLIPSE_CHI2, rtol=1e-4)
        values, vectors = np.linalg.eigh(covariance)
        reach = np.abs(d @ vectors).max(axis=0)
        np.testing.assert_allclose(reach, np.sqrt(ELLIPSE_CHI2 * values), rtol=0.01)
        unweighted = np.cov(poses[:, :2].T, bias=True)
        d0 = outline - poses[:, :2].mean(axis=0)
        assert not np.allclose(np.einsum("ij,jk,ik->i", d0, np.linalg.inv(unweighted), d0), ELLIPSE_CHI2, rtol=0.05)
    stand_in = StandInFilter(poses, weights)
    estimate_outline = rows(path, "/robot/uncertainty/estimate", "strips")[0].reshape(-1, 2).astype(np.float64)
    d = estimate_outline - stand_in.estimate().pose[:2]
    np.testing.assert_allclose(
        np.einsum("ij,jk,ik->i", d, np.linalg.inv(stand_in.covariance[:2, :2]), d), ELLIPSE_CHI2, rtol=1e-4
    )


def test_weighted_covariance_and_ellipse_helpers():
    poses, weights = skewed_particles(40)
    mean, covariance = weighted_position_covariance(poses, 7.0 * weights)  # not normalised
    np.testing.assert_allclose(mean, np.average(poses[:, :2], axis=0, weights=weights))
    np.testing.assert_allclose(covariance, np.cov(poses[:, :2].T, aweights=weights, bias=True))
    circle = covariance_ellipse((1.0, 2.0), np.eye(2), chi2=4.0)
    np.testing.assert_allclose(np.hypot(circle[:, 0] - 1.0, circle[:, 1] - 2.0), 2.0)
    assert np.isnan(covariance_ellipse((0.0, 0.0), np.full((2, 2), np.nan))).all()


def test_particle_headings_are_logged(tmp_path):
    """`particles/headings`: one arrow of HEADING_LENGTH along the heading from each of every ⌈N / max_headings⌉-th
    logged particle (84 of 250 at max_headings = 100), in the field frame; the particles' radius is static."""
    poses, weights = skewed_particles()
    path = tmp_path / "run.rrd"
    with Recorder(path, spl(), particles_every=1, max_headings=100) as recorder:
        recorder.log_step(0, 0.0, StandInFilter(poses, weights))
    origins = rows(path, "/particles/headings", "origins")[0]
    vectors = rows(path, "/particles/headings", "vectors")[0]
    assert origins.shape == vectors.shape == (84, 2)
    np.testing.assert_allclose(origins, poses[::3, :2], atol=1e-6)
    np.testing.assert_allclose(
        vectors, HEADING_LENGTH * np.column_stack([np.cos(poses[::3, 2]), np.sin(poses[::3, 2])]), atol=1e-6
    )
    assert static_rows(path, "/particles", "radii") == [pytest.approx(PARTICLE_RADIUS)]


def test_events_are_a_text_log_with_marks_on_the_plots(tmp_path):
    """`log_event` writes a TextLog line "kind: text" with its level on /events and a mark on
    /events/marks/<kind> at that step; `log_change` only when the value changes; a filter that starts injecting
    particles logs a "reset"; the default blueprint's plots include the marks and it has an event log view."""
    poses, weights = skewed_particles()
    path = tmp_path / "run.rrd"
    qualities = ["poor", "poor", "okay", "okay", "superb", "superb"]
    injected = [0, 0, 0, 30, 30, 0]
    with Recorder(path, spl(), flush_every=4) as recorder:
        for step in range(6):
            recorder.log_step(step, 0.01 * step, StandInFilter(poses, weights, injected[step]))
            recorder.log_change("quality", qualities[step])
            if step == 1:
                recorder.log_event("kidnap", "the robot was carried 3 m", level="WARN")
        with pytest.raises(ArgumentTypeError, match="level"):
            recorder.log_event("kidnap", "x", level="LOUD")
        with pytest.raises(ArgumentTypeError, match="kind"):
            recorder.log_event("Kid nap", "x")
    texts = rows(path, "/events", "text")
    levels = rows(path, "/events", "level")
    logged = sorted((step, text) for step, row in texts.items() for text in row)
    assert logged == [
        (0, "quality: poor"),
        (1, "kidnap: the robot was carried 3 m"),
        (2, "quality: okay"),
        (3, "reset: sensor resetting: 30 of 250 particles injected"),
        (4, "quality: superb"),
    ]
    assert {step: list(row) for step, row in levels.items()} == {
        0: ["INFO"],
        1: ["WARN"],
        2: ["INFO"],
        3: ["INFO"],
        4: ["INFO"],
    }
    assert sorted(rows(path, "/events/marks/kidnap", "scalars")) == [1]
    assert sorted(rows(path, "/events/marks/quality", "scalars")) == [0, 2, 4]
    blueprint = default_blueprint()
    views = [view for view in blueprint.root_container.contents[1].contents]
    plots = [view for view in views if isinstance(view, rrb.TimeSeriesView)]
    assert plots and all("/events/marks/**" in str(view.contents) for view in plots)
    assert any(isinstance(view, rrb.TextLogView) for view in views)


def test_the_log_time_timeline_when_the_origin_is_given(tmp_path):
    """With `origin_ns`, every row is also on LOG_TIMELINE at origin + t (ns); without, that timeline is absent
    and `step` and `time` are there as before."""
    pf, u, observations = bench_setup(30)
    origin = 1_700_000_000_123_456_789
    with_origin, without = tmp_path / "with.rrd", tmp_path / "without.rrd"
    for path, origin_ns in ((with_origin, origin), (without, None)):
        with Recorder(path, pf.field, particles_every=2, origin_ns=origin_ns) as recorder:
            for step in range(5):
                recorder.log_step(step, 0.25 * step, pf, observations=observations)
            recorder.log_event("kidnap", "x")
    timelines = {
        chunk.entity_path: set(chunk.timeline_names)
        for chunk in rrc.RrdReader(str(without)).stream()
        if not chunk.is_static
    }
    assert timelines and all(names == {"step", "time"} for names in timelines.values())
    found = {}
    for chunk in rrc.RrdReader(str(with_origin)).stream():
        if chunk.is_static:
            continue
        assert set(chunk.timeline_names) == {"step", "time", LOG_TIMELINE}, chunk.entity_path
        batch = chunk.to_record_batch()
        stamps = batch.column(batch.schema.names.index(LOG_TIMELINE)).cast("int64").to_pylist()
        for step, stamp in zip(batch.column(batch.schema.names.index("step")).to_pylist(), stamps):
            found.setdefault(chunk.entity_path, {})[step] = stamp
    for entity in ("/entropy/position", "/particles", "/observations", "/events"):
        for step, stamp in found[entity].items():
            assert stamp == origin + 250_000_000 * step, (entity, step)


def chunk_count(path):
    return sum(1 for chunk in rrc.RrdReader(str(path)).stream() if not chunk.is_static)


def test_the_file_is_compact_and_opens_with_its_blueprint(tmp_path):
    """300 steps sent every 10 steps (30 sends per entity): the closed file holds at most 2 temporal chunks per
    entity (one each for 12 entities here), where the same run written without compaction holds 30 per entity;
    the rows are all there, the file keeps its recording id and a blueprint, and `rerun rrd verify` accepts it."""
    pf, u, observations = bench_setup(30)
    compact, plain = tmp_path / "compact.rrd", tmp_path / "plain.rrd"
    for path, compacting in ((compact, True), (plain, False)):
        with Recorder(
            path, pf.field, particles_every=3, flush_every=10, compact=compacting, recording_id="review-test"
        ) as recorder:
            for step in range(300):
                recorder.log_step(step, 0.01 * step, pf, truth=TRUE_POSE, observations=observations)
                if step % 50 == 0:
                    recorder.log_event("quality", f"step {step}")
    entities = {chunk.entity_path for chunk in rrc.RrdReader(str(compact)).stream() if not chunk.is_static}
    assert chunk_count(compact) <= 2 * len(entities) < chunk_count(plain)
    assert chunk_count(plain) >= 30 * 8
    assert sorted(rows(compact, "/entropy/position", "scalars")) == list(range(300))
    assert sorted(rows(compact, "/particles", "positions")) == list(range(0, 300, 3))
    reader = rrc.RrdReader(str(compact))
    assert [entry.recording_id for entry in reader.recordings()] == ["review-test"]
    assert reader.blueprints() and sum(1 for _ in reader.stream(store=reader.blueprints()[0])) > 0
    command = rerun_command()
    if command is not None:
        done = subprocess.run([command, "rrd", "verify", str(compact)], capture_output=True, text=True)
        assert done.returncode == 0, done.stderr[-2000:]
