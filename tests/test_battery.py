"""The evaluation battery: its metrics on hand-made arrays, its simulator, and one short run end to end."""

import json
import math

import numpy as np
import pytest

from demos.battery import localize, run_case, split_seeds, summarize_family
from demos.battery import main as battery_main
from demos.battery_sim import (
    BLACKOUT,
    BURST_SECONDS,
    EVENT_AT,
    FAMILIES,
    FIELDS,
    KIDNAP_DISTANCE,
    LYING,
    MAX_RANGE,
    RANGES,
    SPECIAL_TURNS,
    SPIN_DEG,
    STUCK_EXCESS,
    STUCK_SECONDS,
    field_for,
    kidnap_mirror_log_odds,
    simulate,
)
from field.angles import wrap_angles
from mcl.localizer import Quality
from mcl.tools.evaluation import (
    QUALITY_CODE,
    convergence_time,
    evaluate,
    failed,
    has_stretch,
    hold_last,
    lost_counts,
    mirrored,
    pool_counts,
    pose_errors,
    quality_codes,
    quality_counts,
    tracking_rmse,
)

DT = 0.01


def grid(n):
    return (np.arange(n) + 1) * DT


def still(n, pose=(-2.0, 1.0, 0.3)):
    return np.tile(np.asarray(pose, dtype=float), (n, 1))


def with_error(truth, position):
    """Estimates `position` m ahead of the truth along +x, heading exact."""
    est = truth.copy()
    est[:, 0] += position
    return est


# -- metrics ------------------------------------------------------------------------------------------------


def test_mirrored_stretch_counts_as_mirrored_and_failed():
    truth = still(1000)
    est = truth.copy()
    est[300:600] = [2.0, -1.0, 0.3 + math.pi]  # the point mirror, 3 s
    m = mirrored(truth, est)
    assert m.sum() == 300 and m[300:600].all()
    assert failed(truth, est).sum() == 300
    fig = evaluate(grid(1000), truth, est, np.zeros(1000, np.int8), np.zeros(1000, bool))
    assert fig["mirrored_share"] == pytest.approx(0.3)
    assert fig["fail_share"] == pytest.approx(0.3)
    assert fig["on_mirror"] is True
    # 1.5 s on the mirror: mirrored and failed, but not "on the mirror" (that takes 2 s).
    est2 = truth.copy()
    est2[300:450] = [2.0, -1.0, 0.3 + math.pi]
    assert not evaluate(grid(1000), truth, est2, np.zeros(1000, np.int8), np.zeros(1000, bool))["on_mirror"]
    assert has_stretch(grid(1000), mirrored(truth, est2), 1.5)


def test_mirror_near_the_centre_fails_although_the_position_is_close():
    truth = still(10, (0.1, 0.0, 0.0))
    est = still(10, (-0.1, 0.0, math.pi))  # 0.2 m off, facing the other way: the mirror image
    p, _ = pose_errors(truth, est)
    assert p.max() < 0.5
    assert mirrored(truth, est).all() and failed(truth, est).all()
    # The truth itself is never mirrored, even near the centre where truth and image are close.
    assert not mirrored(truth, truth).any()


def test_convergence_time_is_the_start_of_the_first_second_long_good_stretch():
    n = 1000
    truth = still(n)
    err = np.full(n, 1.0)
    err[250:300] = 0.1  # 0.5 s good: too short
    err[330:] = 0.1  # good for good from sample 330 (t = 3.31 s)
    est = with_error(truth, err)
    p, h = pose_errors(truth, est)
    assert convergence_time(grid(n), p, h) == pytest.approx(3.31)
    assert convergence_time(grid(n), p, h, since=4.0) == pytest.approx(0.0)  # already converged at 4 s
    # Heading counts too: 30° off is not converged, 10° is.
    h30 = np.where(np.arange(n) < 600, math.radians(30), math.radians(10))
    assert convergence_time(grid(n), p, h30) == pytest.approx(6.01)
    # Exactly 1 s of good samples at the end counts; 0.99 s does not ("never" is inf).
    e = np.full(n, 1.0)
    e[900:] = 0.0
    assert convergence_time(grid(n), e, np.zeros(n)) == pytest.approx(9.01)
    e[900] = 1.0
    assert convergence_time(grid(n), e, np.zeros(n)) == math.inf
    assert convergence_time(grid(n), np.full(n, 0.35), np.zeros(n)) == math.inf
    # From an event's end: a window ending at 2.0 s, the estimate good again from 2.5 s.
    e = np.zeros(n)
    e[150:250] = 3.0
    fig = evaluate(grid(n), truth, with_error(truth, e), np.zeros(n, np.int8), np.zeros(n, bool), windows=[(1.5, 2.0)])
    assert fig["reconverge_s"] == pytest.approx(0.51)
    assert fig["converge_s"] == pytest.approx(0.01)


def test_lost_recall_and_false_alarms():
    n = 1000
    t = grid(n)
    err = np.full(n, 0.1)
    err[100:450] = 2.0  # 3.5 s lost: the flag is due from 2 s in (samples 300..449)
    err[700:850] = 2.0  # 1.5 s: too short to be due
    lost = np.zeros(n, bool)
    lost[350:450] = True  # flagged for 100 of the 150 due samples
    lost[600:650] = True  # a false alarm while within 0.3 m (50 samples)
    counts = lost_counts(t, err, lost)
    assert counts["recall"] == {"steps": 150, "lost": 100}
    calm = n - 350 - 150
    assert counts["false_alarm"] == {"steps": calm, "lost": 50}
    # An episode of exactly 2 s is not "more than 2 s".
    e2 = np.full(n, 0.1)
    e2[100:300] = 2.0
    assert lost_counts(t, e2, np.ones(n, bool))["recall"]["steps"] == 0


def test_quality_counts_rmse_and_pooling():
    err = np.array([0.1, 0.6, 0.2, 0.7, 0.9, 0.05])
    q = quality_codes([Quality.SUPERB, Quality.SUPERB, Quality.OKAY, Quality.OKAY, Quality.POOR, Quality.POOR])
    assert (
        q.tolist()
        == [QUALITY_CODE[Quality.SUPERB]] * 2 + [QUALITY_CODE[Quality.OKAY]] * 2 + [QUALITY_CODE[Quality.POOR]] * 2
    )
    c = quality_counts(q, err)
    assert c["SUPERB"] == {"steps": 2, "wrong": 1}
    assert c["OKAY"] == {"steps": 2, "wrong": 1}
    assert c["POOR"] == {"steps": 2, "wrong": 1}
    assert c["superb_coverage"] == {"steps": 3, "superb": 1}  # within 0.3 m: 0.1 (SUPERB), 0.2, 0.05
    fail = err > 0.5
    rp, rh = tracking_rmse(err, np.full(6, 0.1), fail)
    assert rp == pytest.approx(math.sqrt((0.01 + 0.04 + 0.0025) / 3))
    assert rh == pytest.approx(0.1)
    assert tracking_rmse(err, err, np.ones(6, bool)) == (None, None)
    runs = [
        {"quality": c, "lost": {"recall": {"steps": 4, "lost": 1}, "false_alarm": {"steps": 10, "lost": 0}}},
        {"quality": c, "lost": {"recall": {"steps": 0, "lost": 0}, "false_alarm": {"steps": 10, "lost": 2}}},
    ]
    pooled = pool_counts(runs)
    assert pooled["SUPERB"]["share"] == pytest.approx(0.5)
    assert pooled["superb_coverage"]["share"] == pytest.approx(1 / 3)
    assert pooled["recall"]["share"] == pytest.approx(0.25)
    assert pooled["false_alarm"]["share"] == pytest.approx(0.1)


def test_hold_last_puts_estimates_on_the_truth_grid():
    values = np.array([[1.0, 0, 0], [2.0, 0, 0], [3.0, 0, 0]])
    held = hold_last([0.005, 0.01, 0.025, 0.03, 0.5], [0.01, 0.02, 0.03], values)
    assert np.isnan(held[0]).all()
    assert held[1:, 0].tolist() == [1.0, 2.0, 3.0, 3.0]


def test_family_summary_counts_never_and_strong_excess():
    def run(seed, converge, reconverge, excess=None):
        return {
            "seed": seed,
            "field": "spl",
            "converge_s": converge,
            "reconverge_s": reconverge,
            "windows": [[1.0, 2.0]],
            "excess_m": excess,
            "fail_share": 0.1,
            "mirrored_share": 0.0,
            "on_mirror": False,
            "rmse_position_m": 0.1,
            "rmse_heading_deg": 2.0,
            "dropped_frames": 0,
            "quality": quality_counts(np.zeros(3, np.int8), np.zeros(3)),
            "lost": {"recall": {"steps": 0, "lost": 0}, "false_alarm": {"steps": 3, "lost": 0}},
        }

    s = summarize_family([run(0, 1.0, 2.0, 0.7), run(1, 2.0, None, 0.3), run(2, None, 4.0, 0.9)])
    assert s["converge_s"]["never"] == 1 and s["converge_s"]["median"] == 2.0
    assert s["reconverge_s"]["worst"] == math.inf and s["reconverge_s"]["never"] == 1
    assert s["reconverge_strong_excess_s"] == {"median": 3.0, "worst": 4.0, "never": 0, "runs": 2}


# -- simulator ----------------------------------------------------------------------------------------------


def test_same_seed_same_run_bit_for_bit():
    a, b = simulate("false_bursts", 4, 20.0), simulate("false_bursts", 4, 20.0)
    for name in ("times", "start", "truth", "body", "odometry", "walking", "moving"):
        assert np.array_equal(getattr(a, name), getattr(b, name)), name
    assert a.params == b.params and a.calls == b.calls and a.windows == b.windows
    assert len(a.frames) == len(b.frames)
    for fa, fb in zip(a.frames, b.frames):
        assert (fa.capture_time, fa.arrival_step, fa.head) == (fb.capture_time, fb.arrival_step, fb.head)
        for name in ("kinds", "ranges", "bearings"):
            assert np.array_equal(getattr(fa.observations, name), getattr(fb.observations, name))
    c = simulate("false_bursts", 5, 20.0)
    assert not np.array_equal(a.truth[:100], c.truth[:100])
    # The family is part of the seed: the same seed in another family is another run.
    assert not np.array_equal(simulate("tracking", 4, 20.0).odometry, simulate("blackout", 4, 20.0).odometry)


def _within(value, bounds):
    return bounds[0] - 1e-9 <= value <= bounds[1] + 1e-9


@pytest.mark.parametrize("family", FAMILIES)
def test_parameters_and_events_in_their_ranges(family):
    fields = set()
    for seed in range(4):
        run = simulate(family, seed, 60.0)
        p, event = run.params, run.params["event"]
        fields.add(p["field"])
        for key in (
            "max_speed",
            "max_turn",
            "turn_bias",
            "drift_time",
            "step_noise",
            "camera_rate",
            "latency",
            "fov_deg",
            "pan_amplitude_deg",
            "pan_period",
            "min_range",
            "detection",
            "range_a",
            "bearing_sigma",
            "false_rate",
        ):
            assert _within(p[key], RANGES[key]), key
        assert all(_within(s, RANGES["odometry_scale"]) for s in p["odometry_scale"])
        assert _within(p["range_growth"], RANGES["range_b" if p["range_law"] == "linear" else "range_c"])
        assert _within(p["max_range"], MAX_RANGE)
        assert run.start[0] < 0 and run.field.contains(run.truth[:, :2]).all()
        latency = np.array([f.arrival_time - f.capture_time for f in run.frames])
        assert latency.min() >= 0 and latency.max() <= 0.1 + 1e-9
        steps = np.array([f.arrival_step for f in run.frames])
        arrivals = np.array([f.arrival_time for f in run.frames])
        assert (np.diff(arrivals) >= 0).all()
        late = arrivals > DT
        assert ((steps + 1) * DT >= arrivals - 1e-9).all() and (steps[late] * DT < arrivals[late]).all()
        if family in ("tracking", "start_unknown"):
            assert event["type"] == "none" and not run.windows and not run.calls
            continue
        assert _within(event["time"] / 60.0, EVENT_AT)
        if family in ("kidnap", "kidnap_special"):
            k = event["step"]
            jump = run.truth[k, :2] - run.truth[k - 1, :2]
            assert _within(float(np.hypot(*jump)), (KIDNAP_DISTANCE[0] - 0.01, KIDNAP_DISTANCE[1] + 0.01))
            assert np.abs(run.odometry[k, :2]).max() < 0.01  # the odometry sees nothing
            if family == "kidnap_special":
                turn = math.degrees(wrap_angles(run.truth[k, 2] - run.truth[k - 1, 2]))
                assert abs(wrap_angles(math.radians(turn - SPECIAL_TURNS[seed % 4]))) < 0.05
        elif family == "kidnap_announced":
            name = "penalty_return" if seed % 2 == 0 else "manual_placement"
            assert [c.name for c in run.calls] == [name]
            assert run.truth[event["step"], 0] < 0
        elif family == "collision" and event["type"] == "stuck":
            assert _within(event["seconds"], STUCK_SECONDS) and _within(event["excess_target"], STUCK_EXCESS)
            assert _within(event["excess"], (STUCK_EXCESS[0] - 0.1, STUCK_EXCESS[1] + 0.1))
            window = slice(event["step"], event["end_step"] + 1)
            assert np.ptp(run.truth[window, :2], axis=0).max() == 0.0  # the truth stands still
        elif family == "collision":
            assert _within(abs(event["turn_deg"]), SPIN_DEG)
        elif family == "fall":
            assert [c.name for c in run.calls] == ["fallen", "got_up"]
            assert _within(event["lying"], LYING) and event["shift"] <= 0.3
            lying = slice(event["step"], event["end_step"] + 1)
            assert not run.odometry[lying].any()
        elif family == "false_bursts":
            assert 1 <= len(event["bursts"]) <= 4
            assert all(_within(b - a, BURST_SECONDS) for a, b in event["bursts"][:-1])
            inside = [f for f in run.frames if any(a <= f.capture_time <= b for a, b in event["bursts"])]
            assert np.mean([f.false for f in inside]) > 2.0
        elif family == "blackout":
            assert _within(event["length"], BLACKOUT)
            dark = [f for f in run.frames if event["time"] <= f.capture_time <= event["end"]]
            assert dark and all(len(f.observations) == 0 for f in dark)
    assert fields == set(FIELDS)


def test_odometry_differs_from_the_truth_by_the_drawn_errors():
    for seed in range(3):
        run = simulate("tracking", seed, 60.0)
        p = run.params
        # The truth follows the walking engine exactly (no event in this family).
        prev = np.vstack([run.start, run.truth[:-1]])
        d = run.truth[:, :2] - prev[:, :2]
        c, s = np.cos(prev[:, 2]), np.sin(prev[:, 2])
        local = np.column_stack(
            [c * d[:, 0] + s * d[:, 1], -s * d[:, 0] + c * d[:, 1], wrap_angles(run.truth[:, 2] - prev[:, 2])]
        )
        assert np.allclose(local, run.body, atol=1e-12)
        walking = run.walking
        scale = np.asarray(p["odometry_scale"])
        # Scale per axis and the turn bias: a least-squares fit of the odometry on the body motion and a
        # constant rate while walking (which also takes up the mean of the slowly wandering velocity error).
        for axis in (0, 2):
            x, y = run.body[walking, axis], run.odometry[walking, axis]
            design = np.column_stack([x, np.full(x.shape, DT)])
            slope, rate = np.linalg.lstsq(design, y, rcond=None)[0]
            # (the velocity error wanders for seconds, so it correlates a little with the leg speeds)
            assert slope == pytest.approx(scale[axis], abs=0.05 if axis == 0 else 0.03)
            if axis == 2:
                assert rate == pytest.approx(p["turn_bias"], abs=0.02)
        # What is left after scale and bias is the small per-step noise: drift and white noise.
        residual = run.odometry - run.body * scale
        residual[:, 2] -= walking * p["turn_bias"] * DT
        bound = 6 * (
            np.asarray(p["drift_sigma"]) * DT + p["step_noise"] * np.abs(run.body) + np.array([5e-5, 5e-5, 1e-4])
        )
        assert (np.abs(residual) <= bound).all()
        assert not np.allclose(run.odometry, run.body)


def test_detections_only_inside_the_drawn_view():
    for family, seed in (("tracking", 0), ("false_bursts", 1), ("kidnap", 2)):
        run = simulate(family, seed, 30.0)
        p = run.params
        half_fov = math.radians(p["fov_deg"]) / 2
        sigma_max = p["range_a"] + p["range_growth"] * (
            p["max_range"] if p["range_law"] == "linear" else p["max_range"] ** 2
        )
        total = 0
        for frame in run.frames:
            o = frame.observations
            total += len(o)
            off = np.abs(wrap_angles(o.bearings - frame.head))
            assert (off <= half_fov + 5 * p["bearing_sigma"]).all()
            assert (o.ranges <= p["max_range"] + 5 * sigma_max).all()
            # False detections are drawn inside the view exactly.
            assert (off[frame.real :] <= half_fov + 1e-9).all()
            assert len(o) == frame.real + frame.false
            assert np.isnan(o.range_sigmas).all()  # no noise figures passed with the detections
        assert total > 0


# -- end to end ---------------------------------------------------------------------------------------------


def test_short_tracking_run_end_to_end():
    run = simulate("tracking", 3, 8.0)
    out = localize(run, particles=500)
    p, h = pose_errors(run.truth, out["estimates"])
    assert p[-300:].max() < 0.3 and h[-300:].max() < math.radians(20)
    fig = run_case("tracking", 3, 8.0, 500)
    assert fig["converge_s"] is not None and fig["converge_s"] < 5.0
    assert fig["params"]["field"] == "spl" and fig["reconverge_s"] is None
    json.dumps(fig)


def test_command_line(capsys, tmp_path):
    assert split_seeds("train", 3) == [0, 1, 2] and split_seeds("holdout", 2) == [1000, 1001]
    for bad in (
        ["--families", "tracking,nope"],
        ["--split", "dev"],
        ["--seeds", "0"],
        ["--duration", "2"],
        ["--particles", "-5"],
        ["--jobs", "x"],
        ["--prior", "bogus=1"],
        ["--prior", "pool=0"],
        ["--quality", "gate=x"],
        ["--quality", "superb_fit=2"],
        ["--quality", "rivals.nope=1"],
        ["--quality", "rivals.young=-1"],
        ["--sensor", "detection_rate=1"],
        ["--sensor", "field=1"],
        ["--sensor", "bogus=0.1"],
    ):
        with pytest.raises(SystemExit) as exit_info:
            battery_main(bad)
        assert exit_info.value.code == 2
    capsys.readouterr()
    path = tmp_path / "battery.json"
    assert (
        battery_main(
            [
                "--families",
                "tracking",
                "--split",
                "train",
                "--seeds",
                "1",
                "--duration",
                "10",
                "--jobs",
                "1",
                "--json",
                "--save",
                str(path),
            ]
        )
        == 0
    )
    printed = json.loads(capsys.readouterr().out)
    assert printed["splits"]["train"]["seeds"] == [0]
    assert json.loads(path.read_text())["splits"]["train"]["families"]["tracking"]["runs"][0]["seed"] == 0
    # two saved results side by side; a missing split or file is an error
    assert battery_main(["--compare", str(path), str(path), "--split", "train"]) == 0
    compared = capsys.readouterr().out
    assert "tracking" in compared and "lost recall" in compared
    for bad in (["--compare", str(path), str(path)], ["--compare", str(path), str(tmp_path / "none.json")]):
        with pytest.raises(SystemExit) as exit_info:
            battery_main(bad)
        assert exit_info.value.code == 2
    # a variant is labelled as one, in the report and in the results
    assert (
        battery_main(
            [
                "--families",
                "tracking",
                "--split",
                "train",
                "--seeds",
                "1",
                "--duration",
                "10",
                "--jobs",
                "1",
                "--prior",
                "kidnap_sigma=1.5",
                "--quality",
                "lost_after=2",
            ]
        )
        == 0
    )
    report = capsys.readouterr().out
    assert "VARIANT (kidnap_sigma=1.5, lost_after=2.0)" in report


def test_a_view_and_a_sensor_variant_are_labelled_and_the_view_is_passed(capsys):
    assert (
        battery_main(
            [
                "--families",
                "tracking",
                "--split",
                "train",
                "--seeds",
                "1",
                "--duration",
                "10",
                "--jobs",
                "1",
                "--view",
                "--sensor",
                "detection_rate=0.4",
            ]
        )
        == 0
    )
    report = capsys.readouterr().out
    assert "VARIANT (detection_rate=0.4), frames with their camera view" in report
    run = simulate("tracking", 3, 10.0)
    with_view = localize(run, particles=300, view=True)
    without = localize(run, particles=300)
    assert not np.array_equal(with_view["estimates"], without["estimates"])  # the view changes the weights


def test_kidnap_mirror_odds_follow_the_simulators_own_law():
    """The odds the battery splits kidnappings by: +inf when the mirror image lies at a distance the law never
    draws, about even when both lie as far from the start, None for other events."""
    field = field_for(0)  # SPL
    start = [-2.0, 0.5, 0.0]
    far_mirror = {"type": "kidnap", "from": start, "to": [-1.0, -1.0, 1.0]}  # mirror (1, 1): 3.04 m
    assert math.isfinite(kidnap_mirror_log_odds(field, far_mirror))
    clear = {"type": "kidnap_special", "from": start, "to": [-3.5, 1.5, 0.0]}  # mirror (3.5, -1.5): 5.6 m
    assert kidnap_mirror_log_odds(field, clear) == math.inf
    # the start on the centre mark: the landing point and its mirror are equally far, so the odds are even
    even = {"type": "kidnap", "from": [0.0, 0.0, 0.0], "to": [1.5, 1.0, 2.0]}
    assert abs(kidnap_mirror_log_odds(field, even)) < 1e-9
    assert kidnap_mirror_log_odds(field, {"type": "blackout"}) is None
    assert kidnap_mirror_log_odds(field, {"type": "kidnap"}) is None  # not happened yet
    # in the results (JSON has no infinity: None, which the summary reads as certain for a kidnapping)
    fig = run_case("kidnap", 2, 20.0, 300)
    assert fig["event"] == "kidnap" and "kidnap_log_odds" in fig
    summary = summarize_family([fig])
    assert sum(v["runs"] for v in summary["kidnap_odds"].values()) == 1


def test_a_quality_variant_sets_the_rivals_numbers_by_dotted_name():
    from demos.battery import make_localizer
    from field import spl
    from mcl.profile import Profile

    loc = make_localizer(spl(), 0, 50, quality={"rivals.young": 2.0, "superb_rival_odds": 20.0})
    assert loc.thresholds.rivals.young == 2.0 and loc.thresholds.superb_rival_odds == 20.0
    profile = Profile({"rivals": {"keep": 4}})
    assert make_localizer(spl(), 0, 50, quality={"rivals.young": 1.0}, profile=profile).thresholds.rivals.keep == 4
