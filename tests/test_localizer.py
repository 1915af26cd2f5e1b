"""The robot-loop localizer: latency compensation, game-event resets, quality, and replaying logs."""

import math
from dataclasses import replace

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from demos.walk_log import to_robot_log
from demos.walk_sim import WalkScenario, simulate
from field import spl
from field.angles import wrap_angles
from mcl import AugmentedMCL
from mcl.latency import SAME_TIME, MotionHistory, compose, move_back, move_forward
from mcl.localizer import Localizer, Quality, default_kickoff_positions, touchline_poses
from mcl.reference import move_back as move_back_reference
from mcl.tools.replay import motion_events, replay
from motion_models import MotionInput

FIELD = spl()
finite = st.floats(-2.0, 2.0, allow_nan=False)
displacements = st.tuples(st.floats(-0.05, 0.05), st.floats(-0.05, 0.05), st.floats(-0.3, 0.3))


def walk(seed=0, duration=8.0, **changes):
    scenario = replace(WalkScenario(), duration=duration, kidnap_time=None, **changes)
    return scenario, simulate(scenario, seed)


def filter_state(loc):
    pf = loc.filter
    return (pf.poses.copy(), pf.log_weights.copy(), pf.w_slow, pf.w_fast, pf.rng.bit_generator.state)


# -- latency ------------------------------------------------------------------------------------------------
@given(st.lists(displacements, min_size=1, max_size=20), st.tuples(finite, finite, st.floats(-3.1, 3.1)))
def test_history_since_composes_the_steps_and_moving_back_undoes_them(steps, pose):
    history = MotionHistory(keep=10.0)
    for k, step in enumerate(steps):
        history.record(0.01 * (k + 1), 0.01, step)
    total = (0.0, 0.0, 0.0)
    for step in steps:
        total = compose(total, step)
    since = history.since(0.0)
    np.testing.assert_allclose(since, total, atol=1e-12)
    # Walking the steps one by one from a pose ends where moving forward by the total ends.
    start = np.array([pose])
    walked = start.copy()
    for step in steps:
        move_forward(walked, np.array(step), walked)
    ahead = np.empty_like(start)
    move_forward(start, np.array(since), ahead)
    np.testing.assert_allclose(walked[:, :2], ahead[:, :2], atol=1e-9)
    assert abs(math.remainder(walked[0, 2] - ahead[0, 2], 2 * math.pi)) < 1e-9
    back = np.empty_like(start)
    move_back(walked, np.array(since), back)
    np.testing.assert_allclose(back[:, :2], start[:, :2], atol=1e-9)
    assert abs(math.remainder(back[0, 2] - start[0, 2], 2 * math.pi)) < 1e-9


@given(st.lists(st.tuples(finite, finite, st.floats(-3.1, 3.1)), min_size=1, max_size=30), displacements)
def test_move_back_kernel_matches_its_reference(poses, displacement):
    poses = np.array(poses)
    out = np.empty_like(poses)
    move_back(poses, np.array(displacement), out)
    np.testing.assert_array_equal(out, move_back_reference(poses, displacement))


def since_reference(steps, t):
    """`MotionHistory.since` as a pass over every kept step (the steps ending by t skipped)."""
    total = (0.0, 0.0, 0.0)
    for t_end, dt, displacement in steps:
        if t_end <= t + SAME_TIME:
            continue
        share = 1.0 if dt <= 0 or t_end - dt >= t else (t_end - t) / dt
        total = compose(total, displacement if share == 1.0 else tuple(share * v for v in displacement))
    return total


@given(
    st.lists(st.tuples(st.sampled_from([0.0, 0.005, 0.01, 0.02]), displacements), min_size=1, max_size=40),
    st.floats(0.0, 1.0),
    st.sampled_from([0.05, 0.3, 10.0]),
)
def test_history_since_is_the_composition_over_the_steps_after_the_capture(steps, fraction, keep):
    """From the end of the history back to the capture: the same compositions in the same order as a pass
    over every kept step, bit for bit, for captures inside steps, at their ends and after the latest."""
    history = MotionHistory(keep=keep)
    t = 0.0
    for dt, displacement in steps:
        t += dt
        history.record(t, dt, displacement)
    kept = list(history._steps)
    oldest, latest = history.oldest, history.latest
    captures = [oldest + fraction * (latest - oldest), latest, oldest] + [
        t_end + shift for t_end, _, _ in kept[-3:] for shift in (0.0, -0.5 * SAME_TIME, -2 * SAME_TIME)
    ]
    for capture in captures:
        if capture >= oldest:
            assert history.since(capture) == since_reference(kept, capture)


def test_history_takes_the_part_of_a_step_after_the_capture_and_refuses_older_captures():
    history = MotionHistory(keep=0.05)
    for k in range(10):
        history.record(0.01 * (k + 1), 0.01, (0.01, 0.0, 0.0))
    assert history.since(0.1) == (0.0, 0.0, 0.0)
    np.testing.assert_allclose(history.since(0.095), (0.005, 0.0, 0.0), atol=1e-12)
    np.testing.assert_allclose(history.since(0.07), (0.03, 0.0, 0.0), atol=1e-12)
    with pytest.raises(ValueError, match="older than the motion history"):
        history.since(0.01)
    with pytest.raises(ValueError, match="older than the latest"):
        history.record(0.05, 0.01, (0.0, 0.0, 0.0))


def test_compensation_with_zero_latency_equals_no_compensation_bit_for_bit():
    scenario, sim = walk(seed=3)
    log = to_robot_log(sim, latency=0.0)
    results = [replay(log, FIELD, particles=200, seed=3, compensate_latency=c) for c in (True, False)]
    np.testing.assert_array_equal(results[0].estimates, results[1].estimates)
    np.testing.assert_array_equal(results[0].covariances, results[1].covariances)


def test_compensation_brings_a_late_camera_back_to_the_no_latency_accuracy():
    scenario, sim = walk(seed=1, duration=20.0, max_speed=0.4, max_turn_rate=1.5)
    errors = {}
    for name, latency, compensate in (("compensated", 0.15, True), ("late", 0.15, False), ("floor", 0.0, True)):
        result = replay(
            to_robot_log(sim, latency=latency),
            FIELD,
            particles=300,
            seed=1,
            compensate_latency=compensate,
            start=tuple(sim.start),
        )
        errors[name] = float(np.median(result.position_errors[result.has_truth]))
    assert errors["compensated"] < 0.75 * errors["late"], errors
    assert errors["compensated"] < 1.3 * errors["floor"], errors


def test_observation_older_than_the_history_is_refused_and_leaves_the_filter_unchanged():
    loc = Localizer(FIELD, n_particles=100, seed=0, history=0.2)
    for k in range(50):
        loc.motion(0.01 * (k + 1), MotionInput(dt=0.01, command=(0.2, 0.0, 0.1)))
    before = filter_state(loc)
    _, sim = walk(seed=0, duration=1.0)
    with pytest.raises(ValueError, match="older than the motion history"):
        loc.observe(sim.frames[0].observations, capture_time=0.1)
    after = filter_state(loc)
    assert all(np.array_equal(a, b) if isinstance(a, np.ndarray) else a == b for a, b in zip(before, after))
    assert loc.counts["observation older than history"] == 1


@pytest.mark.parametrize("bad", [math.nan, "soon", None])
def test_motion_rejects_bad_times_and_times_going_back(bad):
    loc = Localizer(FIELD, n_particles=50, seed=0)
    loc.motion(1.0, MotionInput(dt=0.01, command=(0.1, 0.0, 0.0)))
    with pytest.raises(ValueError):
        loc.motion(bad, MotionInput(dt=0.01, command=(0.1, 0.0, 0.0)))
    with pytest.raises(ValueError, match="times never go back"):
        loc.motion(0.5, MotionInput(dt=0.01, command=(0.1, 0.0, 0.0)))
    with pytest.raises(ValueError, match="MotionInput"):
        loc.motion(1.1, (0.1, 0.0, 0.0))
    with pytest.raises(ValueError, match="capture_time"):
        loc.observe([], capture_time=math.inf)


# -- game events ------------------------------------------------------------------------------------------
def valid(loc):
    pf = loc.filter
    assert np.isfinite(pf.poses).all() and np.isfinite(pf.log_weights).all()
    assert abs(float(np.sum(pf.weights)) - 1.0) < 1e-12
    assert (np.abs(pf.poses[:, 2]) <= math.pi).all()


def nearest_candidate_distance(poses, candidates):
    d = np.hypot(poses[:, None, 0] - candidates[None, :, 0], poses[:, None, 1] - candidates[None, :, 1])
    heading = np.abs(wrap_angles(poses[:, None, 2] - candidates[None, :, 2]))
    best = np.argmin(d + heading, axis=1)
    return d[np.arange(len(poses)), best], heading[np.arange(len(poses)), best]


@pytest.mark.parametrize("event", ["initial", "penalty", "kickoff", "manual", "manual_poses", "place"])
def test_each_reset_leaves_a_valid_particle_set_in_the_right_region(event):
    loc = Localizer(FIELD, n_particles=400, seed=5)
    hl, hw = FIELD.half_length, FIELD.half_width
    poses = loc.filter.poses
    if event == "initial":
        loc.initial_placement()
        assert (poses[:, 0] < 0.3).all() and (poses[:, 0] > -hl - 0.4).all()
        assert (np.abs(np.abs(poses[:, 1]) - hw) < 0.4).all()
        facing_in = np.sign(poses[:, 1]) == -np.sign(np.sin(poses[:, 2]))
        assert facing_in.all()
        assert 0.4 < np.mean(poses[:, 1] > 0) < 0.6  # both touchlines
    elif event == "penalty":
        loc.penalty_return()
        candidates = touchline_poses(FIELD, [-hl + FIELD.dims.penalty_mark_distance])
        distance, heading = nearest_candidate_distance(poses, candidates)
        assert (distance < 0.8).all() and (heading < 0.8).all()
        assert 0.4 < np.mean(poses[:, 1] > 0) < 0.6
    elif event == "kickoff":
        loc.kickoff_placement(kicking=False)
        distance, heading = nearest_candidate_distance(poses, default_kickoff_positions(FIELD, False))
        assert (distance < 0.8).all() and (heading < 0.8).all()
    elif event == "manual":
        loc.manual_placement()
        assert (poses[:, 0] <= 0).all() and (np.abs(poses[:, 1]) <= hw).all()
        assert np.median(np.abs(poses[:, 2])) < 0.4
    elif event == "manual_poses":
        target = np.array([[-1.0, 1.0, 0.2], [-2.0, -1.0, 0.0]])
        loc.manual_placement(target)
        distance, _ = nearest_candidate_distance(poses, target)
        assert (distance < 0.8).all()
    else:
        loc.place((1.0, 2.0, 3.0))
        distance, heading = nearest_candidate_distance(poses, np.array([[1.0, 2.0, 3.0]]))
        assert (distance < 0.8).all() and (heading < 0.8).all()
    valid(loc)


def test_fallen_robot_ignores_motion_and_detections_and_getting_up_widens_the_belief():
    loc = Localizer(FIELD, n_particles=300, seed=2)
    loc.place((0.0, 0.0, 0.0), sigma=(0.05, 0.05, 0.05))
    before = loc.filter.poses.copy()
    loc.fallen()
    loc.motion(0.01, MotionInput(dt=0.01, command=(0.3, 0.0, 0.0)))
    _, sim = walk(seed=0, duration=0.5)
    assert loc.observe(sim.frames[0].observations) is False
    np.testing.assert_array_equal(loc.filter.poses, before)
    assert loc.quality() is Quality.POOR
    assert loc.counts == {"motion while fallen": 1, "observation while fallen": 1}
    for k in range(2, 400):  # lying for 4 s: POOR, but not lost (it knows why)
        loc.motion(0.01 * k, MotionInput(dt=0.01, command=(0.0, 0.0, 0.0)))
    assert loc.quality() is Quality.POOR and not loc.is_lost
    loc.got_up()
    spread_before = np.std(before, axis=0)
    spread_after = np.std(loc.filter.poses, axis=0)
    assert (spread_after > 2 * spread_before).all()
    valid(loc)


def test_penalty_return_settles_on_the_true_touchline_not_the_other_or_the_mirror():
    from demos.penalty import ending, return_pose

    for seed, side in ((0, 1), (1, -1)):
        scenario, sim = walk(seed=seed, duration=6.0)
        scenario = replace(scenario, start_pose=return_pose(scenario, side))
        sim = simulate(scenario, seed)
        result = replay(to_robot_log(sim), FIELD, particles=300, seed=seed, start="penalty")
        last = result.times >= result.times[-1] - 1.0
        assert ending(result.estimates[last], result.truth[last]) == "true pose"


# -- quality ----------------------------------------------------------------------------------------------
def test_quality_is_superb_while_tracking_and_the_robot_is_lost_when_detections_stop_fitting():
    scenario, sim = walk(seed=4, duration=10.0)
    result = replay(to_robot_log(sim), FIELD, particles=300, seed=4, start=tuple(sim.start))
    tracking = result.times > 1.0
    # mostly SUPERB; the surprise (QualityThresholds.superb_surprise) takes a few stretches of unexplained
    # detections in a row down to OKAY (89 % SUPERB on this walk, 95 % without the surprise)
    assert np.mean(result.quality[tracking] == 2) > 0.85
    assert not result.lost.any()
    # Without injection, a kidnapped filter cannot recover: detections stop fitting and it is lost.
    loc = Localizer(FIELD, n_particles=300, seed=4, augmented=AugmentedMCL(), history=1.0)
    loc.filter.augmented = None
    loc.place(sim.start + np.array([2.5, 1.0, 0.0]), sigma=(0.05, 0.05, 0.05))
    frames = {f.step: f for f in sim.frames}
    lost_at = None
    for k in range(sim.times.shape[0]):
        loc.motion(float(sim.times[k]), MotionInput(dt=sim.dt, command=tuple(sim.commands[k])))
        if k in frames:
            loc.observe(frames[k].observations, capture_time=float(sim.times[k]))
        if loc.is_lost and lost_at is None:
            lost_at = float(sim.times[k])
    assert lost_at is not None and lost_at < 2.0  # the estimate stops explaining the detections: lost within 2 s
    assert loc.fit < 0.2
    loc.place(sim.truth[-1])
    assert not loc.is_lost


# -- replay -----------------------------------------------------------------------------------------------
def test_replaying_a_walk_log_gives_the_estimates_of_feeding_the_filter_directly():
    from demos.walk import run_walk

    scenario, sim = walk(seed=2, duration=5.0)
    direct = run_walk(particles=200, seed=2, scenario=scenario, series=True)["series"]["estimates"]
    replayed = replay(to_robot_log(sim), FIELD, particles=200, seed=2)
    np.testing.assert_allclose(replayed.estimates, direct, atol=1e-9)


def test_odometry_logs_move_the_filter_by_the_odometry_change_in_the_robot_frame():
    from mcl.tools.logs import RobotLog

    pose = np.array([[1.0, 2.0, math.pi / 2], [1.0, 2.1, math.pi / 2 + 0.1]])
    log = RobotLog(odometry_times=[0.0, 0.02], odometry=pose)
    times, inputs = motion_events(log)
    np.testing.assert_allclose(times, [0.02])
    np.testing.assert_allclose(inputs[0].odometry, (0.1, 0.0, 0.1), atol=1e-12)
    assert inputs[0].dt == pytest.approx(0.02)


def test_a_log_that_nothing_moves_is_refused():
    from mcl.tools.logs import LogError, RobotLog

    with pytest.raises(LogError, match="neither odometry"):
        replay(RobotLog(), FIELD)
    with pytest.raises(ValueError, match="poses_out"):
        _, sim = walk(seed=0, duration=0.5)
        replay(to_robot_log(sim), FIELD, particles=50, poses_out="poses.txt")


def test_a_walk_written_to_mcap_replays_to_the_estimates_of_feeding_it_directly(tmp_path):
    from demos.walk import run_walk
    from mcl.tools.logs import read_log, write_log

    scenario, sim = walk(seed=6, duration=4.0)
    direct = run_walk(particles=200, seed=6, scenario=scenario, series=True)["series"]["estimates"]
    for name in ("walk.mcap", "walk.npz", "walk_csv"):
        write_log(to_robot_log(sim), tmp_path / name)
        log, report = read_log(tmp_path / name)
        assert report.complete and report.dropped_total == 0
        replayed = replay(log, FIELD, particles=200, seed=6)
        np.testing.assert_allclose(replayed.estimates, direct, atol=1e-9, err_msg=name)
        np.testing.assert_allclose(replayed.truth[:-1], sim.truth[:-1], atol=1e-9, err_msg=name)


def test_a_truncated_mcap_replays_up_to_where_it_breaks(tmp_path):
    from mcl.tools.logs import read_log
    from mcl.tools.logs.mcap_io import write_mcap

    _, sim = walk(seed=7, duration=6.0)
    path = tmp_path / "walk.mcap"
    write_mcap(to_robot_log(sim, latency=0.05), path, chunk_size=1 << 14)
    data = path.read_bytes()
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(data[: len(data) // 2])
    log, report = read_log(cut)
    assert not report.complete and report.stopped_at is not None and "stopped" in report.summary()
    result = replay(log, FIELD, particles=100, seed=7)
    assert 0 < result.times[-1] <= report.stopped_at + 0.02 < 6.0
    assert np.isfinite(result.estimates).all()


def test_replay_counts_and_names_a_frame_older_than_the_history():
    from mcl.tools.logs import RobotLog, VisionFrame

    _, sim = walk(seed=8, duration=4.0)
    log = to_robot_log(sim)
    late = VisionFrame(stamp=0.5, received=2.5, observations=log.vision[0].observations)
    frames = sorted(log.vision + (late,), key=lambda f: f.received)
    log = RobotLog(
        origin_ns=log.origin_ns,
        command_times=log.command_times,
        commands=log.commands,
        vision=tuple(frames),
        truth_times=log.truth_times,
        truth=log.truth,
    )
    result = replay(log, FIELD, particles=100, seed=8, history=1.0)
    assert result.dropped == {"observation older than history": 1}
    assert result.frames_used == len(frames) - 1
    assert any("arriving at 2.500 s" in note and "captured at 0.500 s" in note for note in result.notes)
    assert "older than history" in result.summary()


def test_replay_recording_holds_the_pose_quality_and_lost_series(tmp_path):
    import rerun.chunk as rrc

    _, sim = walk(seed=9, duration=1.0)
    path = tmp_path / "replay.rrd"
    result = replay(to_robot_log(sim), FIELD, particles=100, seed=9, rrd=str(path))
    entities = {chunk.entity_path for chunk in rrc.RrdReader(str(path)).stream()}
    for expected in (
        "/particles",
        "/robot/estimate",
        "/robot/truth",
        "/localization/quality",
        "/localization/lost",
        "/entropy/position",
    ):
        assert expected in entities
    quality = []
    for chunk in rrc.RrdReader(str(path)).stream():
        if chunk.entity_path == "/localization/quality" and not chunk.is_static:
            batch = chunk.to_record_batch()
            column = next(n for n in batch.schema.names if n.endswith(":scalars"))
            quality.extend(v[0] for v in batch.column(batch.schema.names.index(column)).to_pylist())
    assert sorted(quality) == sorted(result.quality.astype(float).tolist())
