"""The recording: what `Recorder.log_step` buffers is what the .rrd file holds, row by row."""
import math

import numpy as np
import pytest
import rerun.chunk as rrc
from hypothesis import given
from hypothesis import strategies as st

from benchmarks.step import TRUE_POSE, bench_setup
from mcl.recording import LANDMARK_COLORS, Recorder, weight_colors, weight_colors_reference
from field import LandmarkType


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
                expected_colors[step] = weight_colors_reference(pf.weights)
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
    """The compiled colours are `weight_colors_reference`'s, bit for bit: dark blue (lightest) to yellow
    (heaviest), all dark blue when no weight is positive."""
    weights = np.array(weights, dtype=np.float64)
    if case == "zeros":
        weights[:] = 0.0
    elif case == "one NaN" and weights.size:
        weights[weights.size // 2] = np.nan
    colors = weight_colors(weights)
    assert colors.dtype == np.uint8 and colors.shape == (weights.size, 3)
    assert np.array_equal(colors, weight_colors_reference(weights))
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
