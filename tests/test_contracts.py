"""Every motion and sensor model the library ships, and a filter with each, against `mcl.tools.testing`'s contracts.

The models run through `check_motion_model` / `check_sensor_model` (strict: `predict` refuses what `check`
refuses, changing nothing), and a `ParticleFilter` with each through the filter invariants: weights normalized
and poses finite and wrapped after every step, a refused call leaves the filter as it was, the same seed gives
the same run. A contract a model is known to break is a strict xfail below, naming the input: the day the model
keeps it, the test says so.
"""

import copy
import math
import pickle

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from field import spl
from mcl import AugmentedMCL, ParticleFilter
from mcl.tools import testing as mt
from motion_models import (
    AdaptiveMotion,
    ConstantNoise,
    FootstepEvent,
    LearnedFootstepOdometry,
    MotionInput,
    RawFootstepOdometry,
    VelocityLinear,
)
from proprioception.collision import NO_COLLISION
from sensing import CombinedSensorModel, LandmarkSensorModel, LineSensorModel

FIELD = spl()
EXAMPLES = 15
FILTER_SETTINGS = settings(
    max_examples=EXAMPLES, deadline=None, derandomize=True, database=None, suppress_health_check=[HealthCheck.too_slow]
)
STEP = MotionInput(dt=0.01, command=(0.2, 0.0, 0.1), collision=NO_COLLISION)
NOT_STEPPING = MotionInput(dt=0.01)  # neither command nor odometry
NO_PERCEPT = MotionInput(dt=0.01, command=(0.2, 0.0, 0.1))  # the adaptive model needs the collision percept
OLD_EVENT = FootstepEvent(support=1, commanded=(0.04, 0.0, 0.1))  # no sensor-based step: a-priori inputs only


def _learned(kind: str) -> LearnedFootstepOdometry:
    """A tiny trained model: 40 synthetic steps (the sensor step plus noise; the truth 5 % longer)."""
    rng = np.random.default_rng(3)
    commanded = rng.uniform([-0.08, -0.05, -0.4], [0.08, 0.05, 0.4], (41, 3))
    sensor = commanded + rng.normal(0.0, 0.005, commanded.shape)
    support = np.where(np.arange(41) % 2 == 0, 1.0, -1.0)
    duration = rng.uniform(0.1, 1.0, 41)
    if kind == "online":
        inputs = np.column_stack([sensor[1:], sensor[:-1], support[1:], duration[1:], duration[:-1]])
    else:
        inputs = np.column_stack([commanded[1:], commanded[:-1], support[1:]])
    return LearnedFootstepOdometry.train(inputs, 1.05 * commanded[1:], kind, seed=0)


_MADE: dict = {}


def motion_model(name: str):
    """The shipped motion models by name (built once: training the learned ones takes a moment)."""
    if name not in _MADE:
        _MADE[name] = {
            "constant": lambda: ConstantNoise(),
            "constant-gaussian": lambda: ConstantNoise(gaussian=True),
            "velocity-linear": lambda: VelocityLinear(),
            "velocity-linear-gaussian": lambda: VelocityLinear(gaussian=True),
            "adaptive": lambda: AdaptiveMotion(),
            "adaptive-redraw-step": lambda: AdaptiveMotion(redraw="step"),
            "raw-footstep-online": lambda: RawFootstepOdometry("online"),
            "raw-footstep-apriori": lambda: RawFootstepOdometry("apriori"),
            "learned-footstep-online": lambda: _learned("online"),
            "learned-footstep-apriori": lambda: _learned("apriori"),
        }[name]()
    return _MADE[name]


MOTION_MODELS = [
    "constant",
    "constant-gaussian",
    "velocity-linear",
    "velocity-linear-gaussian",
    "adaptive",
    "adaptive-redraw-step",
    "raw-footstep-online",
    "raw-footstep-apriori",
    "learned-footstep-online",
    "learned-footstep-apriori",
]

# What each model must refuse (beyond what `MotionInput` refuses itself).
REFUSED = {
    "constant": [NOT_STEPPING],
    "constant-gaussian": [NOT_STEPPING],
    "velocity-linear": [NOT_STEPPING],
    "velocity-linear-gaussian": [NOT_STEPPING],
    "adaptive": [
        NO_PERCEPT,
        MotionInput(dt=0.01, command=(0.2, 0.0, 0.1), collision="bump"),
        MotionInput(dt=0.01, collision=NO_COLLISION),
    ],
    "raw-footstep-online": [MotionInput(dt=0.01, footstep="swap"), MotionInput(dt=0.01, footstep=OLD_EVENT)],
    "raw-footstep-apriori": [MotionInput(dt=0.01, footstep="swap")],
    "learned-footstep-online": [MotionInput(dt=0.01, footstep="swap"), MotionInput(dt=0.01, footstep=OLD_EVENT)],
    "learned-footstep-apriori": [MotionInput(dt=0.01, footstep=(0.04, 0.0, 0.1))],
}
REFUSED["adaptive-redraw-step"] = REFUSED["adaptive"]


def _within_the_adaptive_speed(u: MotionInput) -> bool:
    """Leaves out odometry over a step so short that `AdaptiveMotion` refuses it (a clock glitch: see
    `test_adaptive_motion_refuses_odometry_over_a_tiny_dt_and_nothing_moves`)."""
    from motion_models.adaptive import MAX_ODOMETRY_SPEED

    return u.odometry is None or u.dt == 0.0 or max(map(abs, u.odometry)) / u.dt <= MAX_ODOMETRY_SPEED


def motion_inputs_for(name: str) -> st.SearchStrategy:
    inputs = mt.motion_inputs("footstep" if "footstep" in name else "any", collision=True)
    return inputs.filter(_within_the_adaptive_speed) if name.startswith("adaptive") else inputs


def hostile_inputs_for(name: str) -> st.SearchStrategy:
    hostile = mt.hostile_motion_inputs()
    return hostile.filter(_within_the_adaptive_speed) if name.startswith("adaptive") else hostile


# -- motion models -----------------------------------------------------------------------------------------------
@pytest.mark.parametrize("name", MOTION_MODELS)
def test_every_shipped_motion_model_keeps_the_contract(name):
    report = mt.check_motion_model(
        motion_model(name),
        FIELD,
        strict=True,
        refused=REFUSED[name],
        inputs=motion_inputs_for(name),
        hostile=hostile_inputs_for(name),
        max_examples=EXAMPLES,
    )
    assert report.examples >= EXAMPLES and report.accepted >= EXAMPLES
    assert report.hostile_refused > 0  # inputs without what the model needs were drawn, and refused


def test_adaptive_motion_refuses_odometry_over_a_tiny_dt_and_nothing_moves():
    """Odometry over a dt so short that its speed overflows when squared (a clock glitch) is refused by `check`
    and by `predict`, before anything moves; in a filter, the step is refused and the filter is unchanged (it
    once gave infinite poses, and the estimate of those crashed the process)."""
    u = MotionInput(dt=1e-300, odometry=(0.0625, 0.0, 0.0), collision=NO_COLLISION)
    mt.assert_motion_contract(AdaptiveMotion(), np.zeros((4, 3)), u, strict=True)
    with pytest.raises(ValueError, match="timestamp glitch"):
        AdaptiveMotion().check(u)
    pf = ParticleFilter(FIELD, AdaptiveMotion(), LandmarkSensorModel(FIELD), n_particles=50, seed=1)
    mt.assert_refused_leaves_state(pf, pf.predict, u)
    pf.predict(MotionInput(dt=0.01, odometry=(0.0625, 0.0, 0.0), collision=NO_COLLISION))  # 6.25 m/s: taken
    mt.assert_poses_finite_and_wrapped(pf.poses)
    assert np.isfinite(pf.estimate().pose).all()


# -- sensor models -----------------------------------------------------------------------------------------------
_LINES = LineSensorModel(FIELD)  # its likelihood field takes a moment to build: once
SENSOR_MODELS = {
    "landmark-von_mises-max": LandmarkSensorModel(FIELD),
    "landmark-von_mises-sum": LandmarkSensorModel(FIELD, mixture="sum"),
    "landmark-exact-max": LandmarkSensorModel(FIELD, bearing_model="exact"),
    "landmark-exact-sum": LandmarkSensorModel(FIELD, bearing_model="exact", mixture="sum"),
    "landmark-linear-noise-no-view": LandmarkSensorModel(FIELD, range_noise_linear=0.05, detection_rate=0.0),
    "lines": _LINES,
    "combined": CombinedSensorModel((LandmarkSensorModel(FIELD), _LINES)),
}


def per_term_bound(model):
    """The documented ceiling: a perfect match scores at most log(1 + outlier weight) per term (0 for the
    max-mixture), so never more than log 2 per term."""
    return lambda observations: model.terms(observations) * math.log(2.0)


@pytest.mark.parametrize("name", list(SENSOR_MODELS))
def test_every_shipped_sensor_model_keeps_the_contract(name):
    model = SENSOR_MODELS[name]
    report = mt.check_sensor_model(model, FIELD, bound=per_term_bound(model), max_examples=EXAMPLES)
    assert report.examples >= EXAMPLES and report.accepted >= EXAMPLES
    assert report.hostile_accepted > 0  # the edge frames are scored (every preset has every landmark type)


# -- the filter with each model --------------------------------------------------------------------------------------
def filter_cases():
    cases = [(name, name, "landmark-von_mises-max") for name in MOTION_MODELS]
    cases += [(f"velocity-linear+{name}", "velocity-linear", name) for name in SENSOR_MODELS]
    return cases


def refusals(motion_name: str) -> st.SearchStrategy:
    """(method name, arguments) of calls a filter must refuse, changing nothing."""
    hostile = mt.hostile_values()
    return st.one_of(
        st.tuples(st.just("step"), st.tuples(hostile)),  # not a MotionInput
        st.tuples(st.just("predict"), st.tuples(hostile)),
        st.tuples(st.just("step"), st.tuples(st.just(STEP), st.sampled_from(["goalpost", [("T", 1.0, 0.2)]]))),
        st.tuples(st.just("step"), st.tuples(st.sampled_from(REFUSED[motion_name]))),
        st.tuples(st.just("reset_around"), st.tuples(hostile)),
        st.tuples(st.just("diffuse"), st.tuples(hostile)),
        st.tuples(st.just("set_particles"), st.tuples(hostile)),
    )


CONFIGURATIONS = st.fixed_dictionaries(
    {
        "resampling": st.sampled_from(["systematic", "stratified", "residual", "multinomial"]),
        "resample_threshold": st.sampled_from([0.0, 0.5, 1.0]),  # never, the default, every correction
        "augmented": st.sampled_from([AugmentedMCL(), None]),
    }
)


@pytest.mark.parametrize("case", filter_cases(), ids=lambda case: case[0])
def test_a_filter_with_every_shipped_model_keeps_its_invariants(case):
    _, motion_name, sensor_name = case
    motion, sensor = motion_model(motion_name), SENSOR_MODELS[sensor_name]
    lines = 12 if sensor_name in ("lines", "combined") else 0

    def frames(pose):
        """Frames of any detections, and frames a robot at `pose` sees (which the filter can explain)."""
        return st.one_of(
            st.none(),
            mt.observations(FIELD, max_detections=5, with_sigmas=True, with_view=True, max_line_points=lines),
            mt.observations(FIELD, max_detections=5, max_line_points=lines, seen_from=pose),
        )

    steps = mt.poses(FIELD, margin=0.5).flatmap(
        lambda pose: st.lists(st.tuples(motion_inputs_for(motion_name), frames(pose)), min_size=1, max_size=5)
    )

    @FILTER_SETTINGS
    @given(
        configuration=CONFIGURATIONS,
        start=st.one_of(st.none(), mt.particle_sets(FIELD, n=48)),
        steps=steps,
        refusal=refusals(motion_name),
    )
    def run(configuration, start, steps, refusal):
        def make():
            return ParticleFilter(FIELD, motion, sensor, n_particles=48, seed=11, **configuration)

        pf = make()
        if start is not None:
            pf.set_particles(*start)
            mt.assert_weights_normalized(pf)
        for u, z in steps:
            pf.step(u, z)
            mt.assert_weights_normalized(pf)
            mt.assert_poses_finite_and_wrapped(pf.poses)
        method, args = refusal
        mt.assert_refused_leaves_state(pf, getattr(pf, method), *args)
        mt.assert_same_seed_same_run(make, steps)

    run()


# -- the fast path ------------------------------------------------------------------------------------------------
# Which shipped models reach the filter's fused compiled step (`mcl.contracts.fast_path`), and that a filter with
# them gives, there, the particles the plain sequence of calls gives (the same models seen through the required
# methods only) bit for bit.
FAST_MOTION = {"constant", "constant-gaussian", "velocity-linear", "velocity-linear-gaussian"}
FAST_SENSORS = {"landmark-von_mises-max", "landmark-exact-max", "landmark-linear-noise-no-view"}


class _Plain:
    """A model with everything but the fast path: its capabilities but `fused_likelihood`, and not a
    `BoundedNoiseModel` (so the filter calls its `predict`)."""

    def __init__(self, model):
        self._model = model

    def __getattr__(self, name):
        if name == "fused_likelihood":
            raise AttributeError(name)
        return getattr(self._model, name)


@pytest.mark.parametrize("name", MOTION_MODELS)
def test_which_shipped_motion_models_get_the_fast_path(name):
    from mcl.contracts import fast_path, moves_by_bounded_noise

    model = motion_model(name)
    assert moves_by_bounded_noise(model) == (name in FAST_MOTION)
    assert fast_path(model, LandmarkSensorModel(FIELD))["step"] == (name in FAST_MOTION)


@pytest.mark.parametrize("name", list(SENSOR_MODELS))
def test_which_shipped_sensor_models_get_the_fast_path(name):
    from mcl.contracts import fast_path

    assert fast_path(VelocityLinear(), SENSOR_MODELS[name])["likelihood"] == (name in FAST_SENSORS)


@pytest.mark.parametrize(
    "motion, sensor", [("velocity-linear", "landmark-von_mises-max"), ("constant-gaussian", "landmark-exact-max")]
)
def test_the_fast_path_gives_the_plain_calls_particles(motion, sensor):
    from mcl.contracts import fast_path
    from sensing import Observations

    plain_motion, plain_sensor = _Plain(motion_model(motion)), _Plain(SENSOR_MODELS[sensor])
    assert not any(fast_path(plain_motion, plain_sensor).values())
    fast = ParticleFilter(FIELD, motion_model(motion), SENSOR_MODELS[sensor], n_particles=200, seed=5)
    plain = ParticleFilter(FIELD, plain_motion, plain_sensor, n_particles=200, seed=5)
    frame = Observations.from_arrays(["goalpost", "T", "L"], [3.0, 2.2, 4.0], [0.3, -0.5, 1.0])
    for k in range(25):
        for pf in (fast, plain):
            pf.step(STEP, frame if k % 2 else None)
        assert fast.poses.tobytes() == plain.poses.tobytes() and fast.weights.tobytes() == plain.weights.tobytes()


@settings(max_examples=EXAMPLES, deadline=None, derandomize=True, database=None)
@given(
    poses=mt.pose_arrays(FIELD, n=(1, 300)),
    observations=mt.observations(FIELD, min_detections=1),
    since=st.none() | st.tuples(*[st.floats(-0.2, 0.2)] * 3),
)
def test_the_fused_kernels_of_every_shipped_sensor_model_equal_its_log_likelihood(poses, observations, since):
    from mcl.contracts import fused_kernels

    offered = [
        name
        for name, model in SENSOR_MODELS.items()
        if mt.assert_fused_likelihood(model, poses, observations.with_view(None), since)
    ]
    assert set(offered) == FAST_SENSORS
    assert all(fused_kernels(SENSOR_MODELS[name]) is not None for name in offered)


def test_a_motion_model_that_returns_nan_poses_does_not_crash_the_filter():
    """A broken model's NaN poses fall in the summary's first cell: the estimate and the entropy are computed,
    not an out-of-bounds write (run in a child process: a crash must fail the test, not end the run)."""
    import subprocess
    import sys

    code = """
import numpy as np
from field import spl
from mcl import ParticleFilter
from motion_models import MotionInput
from sensing import LandmarkSensorModel

class Broken:
    def check(self, u):
        pass
    def predict(self, poses, u, rng):
        poses[::3] = np.nan

pf = ParticleFilter(spl(), Broken(), LandmarkSensorModel(spl()), n_particles=90, seed=0)
pf.predict(MotionInput(dt=0.01, command=(0.1, 0.0, 0.0)))
print("estimate", pf.estimate().weight, "entropy", pf.entropy().position)
"""
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stderr[-2000:]
    assert "estimate" in done.stdout and "entropy" in done.stdout


# -- models a team registers ------------------------------------------------------------------------------------
# Models registered in this process or declared by an installed package (entry points "robocup_mcl.motion_models"
# and "robocup_mcl.sensor_models") go through the same checks; with none installed the parametrized test below
# is reported as skipped (an empty parameter set).
@pytest.mark.parametrize("entry", mt.registered_models(), ids=lambda entry: f"{entry.kind}-{entry.name}")
def test_every_registered_model_keeps_the_contract(entry):
    reports = [
        r for r in mt.check_registered(FIELD, kind=entry.kind, max_examples=EXAMPLES) if r.model.name == entry.name
    ]
    assert len(reports) == 1 and reports[0].contract.accepted > 0


class _Unseeded:
    """A motion model that draws from numpy's global generator: not the same run from the same seed."""

    def check(self, u):
        if u.command is None:
            raise ValueError("needs a command")

    def predict(self, poses, u, rng):
        self.check(u)
        poses[:, :2] += np.random.normal(0.0, 0.01, (poses.shape[0], 2))


class _Shrinking:
    """A motion model that drops particles."""

    def check(self, u):
        pass

    def predict(self, poses, u, rng):
        poses.resize((0, 3), refcheck=False)


@pytest.mark.parametrize("model, says", [(_Unseeded, "same seed"), (_Shrinking, "shape")])
def test_a_registered_model_that_breaks_the_contract_is_named(model, says):
    mt.register_motion_model("broken", model)
    try:
        with pytest.raises(AssertionError, match="broken") as failed:
            mt.check_registered(FIELD, max_examples=5)
        assert says in str(failed.value)
    finally:
        mt.unregister("motion", "broken")
    assert all(entry.name != "broken" for entry in mt.registered_models())


@pytest.mark.parametrize(
    "name, make, refused, error",
    [
        ("", ConstantNoise, (), ValueError),
        ("  ", ConstantNoise, (), ValueError),
        (3, ConstantNoise, (), ValueError),
        ("x", "ConstantNoise", (), TypeError),
        ("x", ConstantNoise, ("not an input",), TypeError),
    ],
)
def test_a_refused_registration_registers_nothing(name, make, refused, error):
    before = mt.registered_models()
    with pytest.raises(error):
        mt.register_motion_model(name, make, refused=refused)
    assert mt.registered_models() == before


def test_a_name_is_registered_once():
    mt.register_sensor_model("once", LandmarkSensorModel)
    try:
        with pytest.raises(ValueError, match="already registered"):
            mt.register_sensor_model("once", LineSensorModel)
        assert [e.make for e in mt.registered_models("sensor") if e.name == "once"] == [LandmarkSensorModel]
    finally:
        mt.unregister("sensor", "once")
    with pytest.raises(KeyError):
        mt.unregister("sensor", "once")


def test_models_declared_by_an_installed_package_are_found(tmp_path, monkeypatch):
    """An entry point of an installed distribution (a dist-info folder on the path) is listed and checked."""
    package = tmp_path / "team_models.py"
    package.write_text(
        "from motion_models import VelocityLinear\n\ndef odometry():\n    return VelocityLinear(gaussian=True)\n"
    )
    info = tmp_path / "team_models-1.0.dist-info"
    info.mkdir()
    (info / "METADATA").write_text("Metadata-Version: 2.1\nName: team-models\nVersion: 1.0\n")
    (info / "entry_points.txt").write_text("[robocup_mcl.motion_models]\nteam-odometry = team_models:odometry\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    found = [e for e in mt.registered_models("motion") if e.name == "team-odometry"]
    assert len(found) == 1 and found[0].source == "entry point team_models:odometry"
    reports = [r for r in mt.check_registered(FIELD, kind="motion", max_examples=5) if r.model.name == "team-odometry"]
    assert len(reports) == 1 and reports[0].fast_path["motion"]


# -- copies ------------------------------------------------------------------------------------------------------
def _array_types(value, path="", depth=0):
    """numba's type of every numpy array reachable from `value` (attributes, tuples, lists, dicts), by path."""
    import numba

    from mcl.numba_cache import PACKAGES

    if isinstance(value, np.ndarray):
        return {path: numba.typeof(value)} if value.dtype != object else {}
    if depth > 4:
        return {}
    if isinstance(value, (tuple, list)):
        items = enumerate(value)
    elif isinstance(value, dict):
        items = value.items()
    elif (
        hasattr(value, "__dict__")
        and not isinstance(value, type)
        and type(value).__module__.split(".")[0] in PACKAGES  # the project's own objects
    ):
        items = vars(value).items()
    else:
        return {}
    found = {}
    for key, item in items:
        found.update(_array_types(item, f"{path}.{key}", depth + 1))
    return found


COPIES = {"deepcopy": copy.deepcopy, "pickle": lambda value: pickle.loads(pickle.dumps(value))}


@pytest.mark.parametrize("how", list(COPIES))
@pytest.mark.parametrize("name", list(SENSOR_MODELS) + MOTION_MODELS)
def test_a_copied_model_holds_arrays_of_the_same_types(name, how):
    """A copy (deepcopy, pickle: a Ray task's arguments) keeps every read-only array read-only: its kernels are
    those the original compiled, and a caller cannot change the copy's tables either."""
    model = SENSOR_MODELS[name] if name in SENSOR_MODELS else motion_model(name)
    types, copied = _array_types(model), _array_types(COPIES[how](model))
    assert copied.items() <= types.items()  # (a model's memo of derived tables starts empty in a copy)
    assert copied or not types
