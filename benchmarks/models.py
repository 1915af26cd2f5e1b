"""The per-call costs `robocup-mcl bench` reports beside the filter step: LWPR, the velocity EKF, and the calls of
the README's robot loop.

    from benchmarks.models import time_lwpr, time_ekf, time_robot_loop

LWPR (`motion_models.lwpr`), 2 inputs and 1 output: the model of the cross benchmark (`demos.lwpr_cross`) after
its 20 training epochs; µs per `update` in steady state and per `predict` of one point, as that benchmark
times them (best of a few repetitions, validation and numba dispatch included). The velocity EKF
(`proprioception.velocity.VelocityEKF`): µs per `predict` (one IMU sample) and per `correct` (one leg-kinematics
velocity), public calls with their validation, for the default filter (gyro bias in the state, 9 states)
and the paper's as written (6 states, eq. 24's first-order Jacobian). The robot loop (`time_robot_loop`): the
public calls of the README's "Using it in a robot's loop", 500 particles, in µs per call: a frame without
detections (a motion input, `predict`, `estimate()`, `entropy()`), `predict` alone (on a filter of its own), `correct` with a list of
three `LandmarkObservation` (the batch built from the list included), that batch alone
(`Observations.from_list`), and a batch of 10 detections from arrays (`Observations.from_arrays`, types as
integers); and the team-integration loop's `Localizer` on a walking robot: a frame (`motion`, `pose`,
`quality`) and `observe` of a batch of three detections captured 30 ms earlier (latency compensated).

Between frames (`time_between_frames`): the benchmark's full step and the issue's step shape at N <= 1 000, each
call made after the thread has slept 10 ms, as a 100 Hz loop makes it. The other timings call the step back
to back or interleaved with other work; this one says what a robot's loop pays once the step's code and data
have had a frame's time to leave the caches (on a shared machine, other tenants evict them meanwhile).
"""

from __future__ import annotations

import statistics
import time

import numba
import numpy as np

from .step import full_step_work, issue_step_work, measure

FRAME_S = 0.01  # the sleep before each call of `time_between_frames`: a 100 Hz loop


def time_lwpr(seed: int = 0) -> dict:
    from demos.lwpr_cross import make_model, run_seed

    warm = make_model()  # load (or compile) the kernels outside the timings
    warm.update(np.zeros(2), np.zeros(1))
    warm.predict(np.zeros(2))
    run = run_seed(seed)
    return {
        "inputs": 2,
        "outputs": 1,
        "receptive_fields": run["num_rfs"],
        "nmse": run["nmse"],
        "update_us": run["us_per_update"],
        "predict_us": run["us_per_predict"],
        "predict_batched_us_per_point": run["us_per_predict_batched"],
        "method": "demos.lwpr_cross.run_seed: the cross benchmark's model after 20 epochs, best of repetitions",
    }


def time_ekf(budget_s: float = 0.3) -> dict:
    from proprioception.velocity import VelocityEKF, VelocityEKFParams

    gravity = np.array([0.0, 0.0, 9.81])
    gyro, accel = np.array([0.01, -0.02, 0.3]), np.array([0.1, 0.05, 9.8])
    measured = np.array([0.2, 0.01, 0.0])
    result = {}
    for label, params in (
        ("default", VelocityEKFParams()),
        ("paper", VelocityEKFParams(estimate_gyro_bias=False, exact_jacobian=False)),
    ):
        ekf = VelocityEKF(gravity, 0.0, params=params)
        clock = {"t": 0.0}

        def predict(ekf=ekf, clock=clock):
            clock["t"] += 0.01
            ekf.predict(clock["t"], gyro, accel)

        timed = measure(
            {"predict": predict, "correct": lambda ekf=ekf: ekf.correct(measured)}, budget_s, min_samples=20
        )
        result[label] = {
            "state_size": params.state_size,
            "predict_us": 1e6 * timed["predict"]["s"],
            "correct_us": 1e6 * timed["correct"]["s"],
        }
    return result


def time_robot_loop(budget_s: float = 0.3, n: int = 500) -> dict:
    from field import spl
    from mcl.filter import ParticleFilter
    from mcl.localizer import Localizer
    from motion_models import MotionInput, VelocityLinear
    from sensing import LandmarkObservation, LandmarkSensorModel, Observations

    def make():
        field = spl()
        pf = ParticleFilter(field, VelocityLinear(), LandmarkSensorModel(field), n_particles=n, seed=0)
        pf.reset_around(np.array([-2.0, 0.0, np.pi]), (0.2, 0.2, 0.1))
        return pf

    looping, predicting = make(), make()  # predict alone on a filter of its own
    u = MotionInput(dt=0.01, command=(0.2, 0.0, 0.1))
    seen = [
        LandmarkObservation("penalty_mark", 1.2, 0.0),
        LandmarkObservation("goalpost", 2.65, 0.31),
        LandmarkObservation("goalpost", 2.65, -0.31),
    ]
    kinds = np.zeros(10, dtype=np.int64)
    ranges, bearings = np.linspace(1.0, 5.0, 10), np.linspace(-0.5, 0.5, 10)

    def frame():
        looping.predict(MotionInput(dt=0.01, command=(0.2, 0.0, 0.1)))
        looping.estimate()
        looping.entropy()

    # The team-integration loop: a walking robot's Localizer, camera frames 30 ms old (scored where each particle
    # was at capture).
    localizer = Localizer(spl(), n_particles=n, seed=0)
    localizer.place(np.array([-2.0, 0.0, np.pi]))
    clock = {"t": 0.0}
    odometry = MotionInput(dt=0.01, odometry=(0.003, 0.0, 0.001))
    batch = Observations.from_list(seen)

    def localizer_frame():
        clock["t"] += 0.01
        localizer.motion(clock["t"], odometry)
        localizer.pose()
        localizer.quality()

    for _ in range(10):  # a motion history to reach back into
        localizer_frame()
    # past the first seconds of its track (`mcl.rivals`' young track, timed on its own below): the steady state
    for _ in range(800):
        localizer_frame()
        if round(clock["t"] * 100) % 3 == 0:
            localizer.observe(batch, capture_time=clock["t"] - 0.03)

    # A young track (`mcl.rivals`): after a reset over the own half, every frame also looks for rival places;
    # a frame at 30 Hz, the track kept young (a re-localization's new track every 5 s).
    young = Localizer(spl(), n_particles=n, seed=0)
    young.anywhere_in_own_half()
    young_clock = {"t": 0.0, "start": 0.0}

    def young_frame():
        young_clock["t"] += 1 / 30
        young.motion(young_clock["t"], MotionInput(dt=1 / 30, odometry=(0.01, 0.0, 0.003)))
        young.observe(batch, capture_time=young_clock["t"] - 0.03)
        rivals = getattr(young, "rivals", None)
        if rivals is not None and young_clock["t"] - young_clock["start"] > 5.0:
            rivals.new_track(young_clock["t"])
            young_clock["start"] = young_clock["t"]

    for _ in range(30):
        young_frame()
    timed = measure(
        {
            "frame": frame,
            "predict": lambda: predicting.predict(u),
            "correct": lambda: looping.correct(seen),
            "from_list": lambda: Observations.from_list(seen),
            "from_arrays": lambda: Observations.from_arrays(kinds, ranges, bearings),
            "localizer_frame": localizer_frame,
            "observe": lambda: localizer.observe(batch, capture_time=clock["t"] - 0.03),
        },
        budget_s,
        min_samples=20,
    )
    # apart, so that its larger working set does not disturb the calls above
    timed.update(measure({"young": young_frame}, budget_s, min_samples=20))
    us = {key: 1e6 * value["s"] for key, value in timed.items()}
    return {
        "particles": n,
        "frame_us": us["frame"],
        "predict_us": us["predict"],
        "correct_list_us": us["correct"],
        "from_list_us": us["from_list"],
        "from_arrays_us": us["from_arrays"],
        "localizer_frame_us": us["localizer_frame"],
        "localizer_observe_us": us["observe"],
        "localizer_young_frame_us": us["young"],
        "method": "benchmarks.models.time_robot_loop: the README loop's calls, interleaved medians",
    }


@numba.njit(cache=True)
def _first(values):
    """A compiled call that does next to nothing (the between-frames baseline)."""
    return values[0]


def _nothing():
    """A Python call that does nothing (the between-frames baseline)."""


def time_between_frames(sizes, samples: int = 40, idle_s: float = FRAME_S) -> dict:
    """Median µs of one call made after sleeping `idle_s`, for the full step (`pf.step` and `pf.entropy()`, as
    the step table times it) and the issue's step shape (one dispatch) at each N of `sizes` up to 1 000, and, as
    the machine's baseline, a Python function that does nothing and a compiled function given one array.
    The items alternate, `samples` calls each; `back_to_back_us` holds the baselines called in a loop."""
    clock = time.perf_counter
    array = np.ones(4)
    baseline = {"python_call": _nothing, "numba_call": lambda: _first(array)}
    work = dict(baseline)
    small = sorted(n for n in set(sizes) if n <= 1_000)
    for n in small:
        work[f"full_step/{n}"] = full_step_work(n)
        work[f"issue_step/{n}"] = issue_step_work(n)
    for fn in work.values():  # load the kernels, warm the buffers
        fn()
        fn()
    times: dict[str, list[float]] = {name: [] for name in work}
    for _ in range(samples):
        for name, fn in work.items():
            time.sleep(idle_s)
            start = clock()
            fn()
            times[name].append(clock() - start)
    us = {name: 1e6 * statistics.median(seconds) for name, seconds in times.items()}
    warm = measure(baseline, budget_s=0.01, min_samples=20)
    return {
        "idle_s": idle_s,
        "samples": samples,
        "rows": [{"n": n, "full_step_us": us[f"full_step/{n}"], "issue_step_us": us[f"issue_step/{n}"]} for n in small],
        "python_call_us": us["python_call"],
        "numba_call_us": us["numba_call"],
        "back_to_back_us": {name: 1e6 * entry["s"] for name, entry in warm.items()},
        "method": "benchmarks.models.time_between_frames: one call after each sleep, medians",
    }
