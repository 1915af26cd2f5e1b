"""Contract checks of any motion or sensor model, the library's or a team's own: one example
(`assert_motion_contract`, `assert_sensor_contract`, `assert_fused_likelihood`) or a hypothesis search
(`check_motion_model`, `check_sensor_model`)."""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from hypothesis import HealthCheck, Phase, given, settings
from hypothesis import strategies as st
from numpy.typing import ArrayLike

from field import Field, spl
from field.checks import LARGEST_COORDINATE
from mcl.tools.testing.invariants import _array_difference, _copy, _frozen, assert_poses_finite_and_wrapped
from mcl.tools.testing.strategies import (
    REFUSALS,
    _preset,
    edge_observations,
    hostile_motion_inputs,
    motion_inputs,
    observations,
    pose_arrays,
)
from motion_models import MotionInput
from sensing import Observations

if TYPE_CHECKING:
    from mcl.contracts import MotionModel, SensorModel


@dataclass
class ContractReport:
    """What a contract check saw, counted over every example hypothesis ran (shrinking included).

    Attributes
    ----------
    examples : int
        Examples run.
    accepted, refused : int
        Inputs from the good strategy the model accepted and refused.
    hostile_accepted, hostile_refused : int
        Inputs from the hostile strategy the model accepted and refused.
    """

    examples: int = 0
    accepted: int = 0
    refused: int = 0
    hostile_accepted: int = 0
    hostile_refused: int = 0


def _name(model) -> str:
    return type(model).__name__


def _poses_copy(poses) -> np.ndarray:
    array = np.array(poses, dtype=np.float64, order="C", copy=True)
    if array.ndim != 2 or array.shape[1] != 3:
        raise ValueError(f"poses must have shape (N, 3), got {array.shape}")
    return array


def _fresh_state(model, n: int) -> np.ndarray | None:
    make = getattr(model, "particle_state", None)
    if not callable(make):
        return None
    try:
        state = np.ascontiguousarray(make(n))
    except Exception as error:
        raise AssertionError(f"{_name(model)}.particle_state({n}) raised {type(error).__name__}: {error}") from error
    assert state.ndim >= 1 and state.shape[0] == n, (
        f"{_name(model)}.particle_state({n}) must have {n} rows, got shape {state.shape}"
    )
    return state


def _predict(model, poses: np.ndarray, u: MotionInput, seed: int, state: np.ndarray | None):
    rng = np.random.default_rng(seed)
    if state is None:
        model.predict(poses, u, rng)
    else:
        model.predict(poses, u, rng, state=state)
    return rng


def assert_motion_contract(
    model: MotionModel, poses: ArrayLike, u: MotionInput, seed: int = 0, *, strict: bool = False
) -> bool:
    """Check one motion input against a motion model's contract.

    `model.check(u)` either refuses with ValueError/TypeError (any other exception fails), or accepts; then
    `model.predict` on a copy of `poses` (with ``state=model.particle_state(N)`` when the model has
    `particle_state`) must not raise, must keep the (N, 3) float64 shape, give finite poses with headings in
    [-π, π], keep the state's rows (and keep it finite), and give the same poses, state and generator state,
    bit for bit, when run again from the same seed.

    Parameters
    ----------
    model : motion model
        Anything with `check(u)` and `predict(poses, u, rng)` (and optionally `particle_state(n)`).
    poses : array_like
        The particles (N, 3); not changed (the model moves a copy).
    u : motion_models.MotionInput
        The input.
    seed : int, optional
        Seed of the generators given to `predict` (default 0).
    strict : bool, optional
        Also require that `predict` refuses what `check` refuses (ValueError/TypeError), before it changes
        the poses, the state or the generator: a model used outside a filter must validate its input. A filter
        calls `check` first, so a model can keep the contract without this (default False).

    Returns
    -------
    bool
        Whether `check` accepted `u`.

    Raises
    ------
    AssertionError
        Naming the model, the input and the property that failed.
    """
    name = _name(model)
    start = _poses_copy(poses)
    n = start.shape[0]
    try:
        model.check(u)
    except REFUSALS as error:
        if strict:
            _assert_predict_refuses(model, start, u, seed, error)
        return False
    except Exception as error:
        raise AssertionError(
            f"{name}.check({u!r}) raised {type(error).__name__}: {error}; a refused input must "
            "raise ValueError or TypeError"
        ) from error
    results = []
    for _ in range(2):
        moved = start.copy()
        state = _fresh_state(model, n)
        state_shape = None if state is None else state.shape
        try:
            rng = _predict(model, moved, u, seed, state)
        except Exception as error:
            raise AssertionError(
                f"{name}.check accepted {u!r} but predict raised {type(error).__name__}: {error}"
            ) from error
        assert moved.shape == (n, 3) and moved.dtype == np.float64, (
            f"{name}.predict changed the poses' shape or dtype to {moved.dtype} {moved.shape} (input {u!r})"
        )
        try:
            assert_poses_finite_and_wrapped(moved)
        except AssertionError as error:
            raise AssertionError(f"{name}.predict with {u!r}: {error}") from None
        if state is not None:
            assert state.shape == state_shape, (
                f"{name}.predict changed the state's shape from {state_shape} to {state.shape} (input {u!r})"
            )
            if state.dtype.kind in "fc":
                assert np.isfinite(state).all(), f"{name}.predict left a non-finite particle state (input {u!r})"
        results.append((moved, state, _frozen(rng.bit_generator.state)))
    (first, first_state, first_rng), (second, second_state, second_rng) = results
    for label, a, b in (("poses", first, second), ("state", first_state, second_state)):
        difference = _array_difference(label, a, b)
        if difference:
            raise AssertionError(
                f"{name}.predict from the same seed gave different results: {difference} "
                f"(input {u!r}); it must draw only from the generator it is given"
            )
    assert first_rng == second_rng, (
        f"{name}.predict from the same seed left the generator in different states (input {u!r})"
    )
    return True


def _assert_predict_refuses(model, start: np.ndarray, u: MotionInput, seed: int, refusal: BaseException) -> None:
    name = _name(model)
    moved = start.copy()
    state = _fresh_state(model, start.shape[0])
    state_before = None if state is None else state.copy()
    rng = np.random.default_rng(seed)
    rng_before = _frozen(rng.bit_generator.state)
    try:
        if state is None:
            model.predict(moved, u, rng)
        else:
            model.predict(moved, u, rng, state=state)
    except REFUSALS:
        pass
    except Exception as error:
        raise AssertionError(
            f"{name}.predict({u!r}) raised {type(error).__name__}: {error}; check refused it "
            f"({type(refusal).__name__}), predict must refuse it with ValueError or "
            "TypeError"
        ) from error
    else:
        raise AssertionError(
            f"{name}.check refused {u!r} ({type(refusal).__name__}: {refusal}) but predict accepted it"
        )
    difference = _array_difference("poses", start, moved) or _array_difference("state", state_before, state)
    if difference:
        raise AssertionError(f"{name}.predict refused {u!r} but changed {difference}")
    assert _frozen(rng.bit_generator.state) == rng_before, f"{name}.predict refused {u!r} but drew random numbers first"


def _run(test: Callable, max_examples: int, strategies: dict, shrink: bool | None) -> None:
    """Run `test` on `max_examples` examples drawn from `strategies`: the same examples on every run, nothing
    stored; the phases of the loaded hypothesis profile unless `shrink` says whether to shrink a failure."""
    configured = settings(
        max_examples=max_examples,
        deadline=None,
        derandomize=True,
        database=None,
        suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large, HealthCheck.filter_too_much],
    )
    if shrink is not None:
        configured = settings(
            configured, phases=tuple(Phase) if shrink else (Phase.explicit, Phase.reuse, Phase.generate)
        )
    configured(given(**strategies)(test))()


def check_motion_model(
    model: MotionModel,
    field: Field | None = None,
    *,
    n: int | tuple[int, int] = (1, 64),
    inputs: st.SearchStrategy | None = None,
    hostile: st.SearchStrategy | None = None,
    refused: Sequence[MotionInput] = (),
    strict: bool = False,
    max_examples: int = 20,
    shrink: bool | None = None,
) -> ContractReport:
    """Check a motion model against the contract the filter relies on, on examples hypothesis draws.

    Each example runs `assert_motion_contract` on particles on the carpet, for an input from `inputs` and one
    from `hostile`. Runs its own hypothesis search: call it from a plain test, not inside ``@given``.

    Parameters
    ----------
    model : motion model
        Anything with `check(u)` and `predict(poses, u, rng)`, optionally `particle_state(n)` (then used as
        ``predict(poses, u, rng, state=state)``).
    field : field.Field, optional
        Particles lie on its carpet (default: `field.spl()`).
    n : int or (int, int), optional
        Particles per example (default 1 to 64).
    inputs : hypothesis strategy of MotionInput, optional
        Inputs the model should take (default ``motion_inputs("any", collision=True)``: commands, odometry and
        footstep events, each with a collision percept). The model may refuse some, not all.
    hostile : hypothesis strategy of MotionInput, optional
        Inputs to accept or refuse cleanly (default `hostile_motion_inputs()`).
    refused : sequence of MotionInput, optional
        Inputs the model must refuse with ValueError/TypeError (checked first, once each).
    strict : bool, optional
        `predict` must refuse what `check` refuses, changing nothing (see `assert_motion_contract`).
    max_examples : int, optional
        Examples to run (default 20).
    shrink : bool, optional
        Whether hypothesis shrinks a failing example to a small one (slower) or reports the first it finds;
        default None: as the loaded hypothesis profile's phases say (all of them, unless a profile leaves
        shrinking out).

    Returns
    -------
    ContractReport
        How many inputs were accepted and refused.

    Raises
    ------
    AssertionError
        On the first property that fails (after hypothesis has shrunk the example), or when the model
        refuses every input from `inputs`.
    """
    field = _preset(spl) if field is None else field
    report = ContractReport()
    start = np.zeros((3, 3))
    for u in refused:
        try:
            model.check(u)
        except REFUSALS:
            pass
        except Exception as error:
            raise AssertionError(
                f"{_name(model)}.check({u!r}) raised {type(error).__name__}: {error}; it must "
                "refuse with ValueError or TypeError"
            ) from error
        else:
            raise AssertionError(f"{_name(model)}.check accepted {u!r}, which it must refuse")
        assert not assert_motion_contract(model, start, u, strict=strict)

    def test(poses, u, bad, seed):
        report.examples += 1
        if assert_motion_contract(model, poses, u, seed, strict=strict):
            report.accepted += 1
        else:
            report.refused += 1
        if assert_motion_contract(model, poses, bad, seed, strict=strict):
            report.hostile_accepted += 1
        else:
            report.hostile_refused += 1

    _run(
        test,
        max_examples,
        dict(
            poses=pose_arrays(field, n),
            u=motion_inputs("any", collision=True) if inputs is None else inputs,
            bad=hostile_motion_inputs() if hostile is None else hostile,
            seed=st.integers(0, 2**63 - 1),
        ),
        shrink,
    )
    assert report.accepted > 0, (
        f"{_name(model)} refused all {report.refused} inputs drawn: give `inputs=` a strategy of the inputs it takes"
    )
    return report


_OBSERVATION_ARRAYS = ("kinds", "ranges", "bearings", "range_sigmas", "bearing_sigmas", "line_points")


def _observation_image(observations) -> tuple:
    return tuple((name, _copy(getattr(observations, name, None))) for name in _OBSERVATION_ARRAYS) + (
        ("view", repr(getattr(observations, "view", None))),
    )


def _bound_of(bound, observations) -> float | None:
    if bound is None:
        return None
    return float(bound(observations)) if callable(bound) else float(bound)


def assert_fused_likelihood(
    model: SensorModel, poses: ArrayLike, observations: Observations, since: Sequence[float] | np.ndarray | None = None
) -> bool:
    """The sensor model's fused-likelihood kernels (`sensing.fused`), run as the filter's fused step runs them,
    give `log_likelihood` bit for bit; with `since` (camera latency), `log_likelihood` of the poses moved back.

    Parameters
    ----------
    model : sensor model
        Any sensor model; one without the capability (`fused_likelihood` absent or returning None) passes.
    poses : array_like, (N, 3)
        The particles.
    observations : Observations
        A frame the model accepts (no camera view: a frame with one is scored through `log_likelihood`).
    since : sequence of 3 floats, optional
        The robot's motion (dx, dy, dθ) since the frame was captured.

    Returns
    -------
    bool
        Whether the model offers the capability (and so was compared).

    Raises
    ------
    AssertionError
        Naming the first particle whose scores differ.
    """
    from mcl.contracts import fused_kernels
    from mcl.latency import move_back
    from mcl.step import NO_SINCE, STEP_BLOCK, fused_step

    kernels = fused_kernels(model)
    if kernels is None:
        return False
    poses = np.ascontiguousarray(poses, dtype=np.float64)
    n = poses.shape[0]
    displacement = NO_SINCE if since is None else np.asarray(since, dtype=np.float64)
    frame, missing = kernels.prepare(kernels.inputs(observations), kernels.params)
    assert missing < 0, f"the kernels refuse detection {missing}, which `check` accepted"
    fused = np.empty(n)
    work = kernels.workspace(frame, min(max(n, 1), STEP_BLOCK))
    copying = (False, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, False, np.empty((0, 3)))
    fused_step(kernels).predict_and_score(
        poses, np.empty_like(poses), np.empty((n, 2)), fused, copying, (0, 0), frame, work, 0, n, False, displacement
    )
    scored = poses
    if since is not None:
        scored = np.empty_like(poses)
        move_back(poses, displacement, scored)
    plain = np.asarray(model.log_likelihood(scored, observations), dtype=np.float64)
    differ = np.flatnonzero(fused.view(np.int64) != plain.view(np.int64))
    assert differ.size == 0, (
        f"{_name(model)}: the fused kernels score particle {differ[0]} "
        f"{fused[differ[0]]!r}, log_likelihood {plain[differ[0]]!r}"
    )
    return True


def assert_sensor_contract(
    model: SensorModel,
    poses: ArrayLike,
    observations: Observations,
    *,
    bound: float | Callable[[Observations], float] | None = None,
    allow_neg_inf: bool = False,
) -> bool:
    """Check one frame against a sensor model's contract.

    `model.check(observations)` either refuses with ValueError/TypeError (any other exception fails), or
    accepts; then `terms(observations)`, when the model has it, is an int >= 0, and
    `log_likelihood(poses, observations, out=buffer)`, called as the filter calls it, returns shape (N,) floats
    without NaN or +inf (-inf only with `allow_neg_inf`), at most `bound`; it leaves the poses and the
    observations as they were; and called again, with or without `out`, it returns the same values bit for bit.

    Parameters
    ----------
    model : sensor model
        Anything with `check(observations)` and `log_likelihood(poses, observations, out=None)`, optionally
        `terms(observations)`.
    poses : array_like
        The particles (N, 3); the model scores a copy.
    observations : sensing.Observations
        The frame.
    bound : float or callable, optional
        The largest log-likelihood accepted, or a function of the observations giving it (e.g. the number
        of terms times the largest log-likelihood of one); default None: any finite value.
    allow_neg_inf : bool, optional
        Accept -inf (a particle that cannot explain the frame; the filter handles it). Default False: the
        library's models give finite values for every frame they accept.

    Returns
    -------
    bool
        Whether `check` accepted the observations.

    Raises
    ------
    AssertionError
        Naming the model, the property and the first particle that breaks it.
    """
    name = _name(model)
    start = _poses_copy(poses)
    n = start.shape[0]
    try:
        model.check(observations)
    except REFUSALS:
        return False
    except Exception as error:
        raise AssertionError(
            f"{name}.check raised {type(error).__name__}: {error}; refused observations must "
            "raise ValueError or TypeError"
        ) from error
    terms = getattr(model, "terms", None)
    if callable(terms):
        count = terms(observations)
        assert isinstance(count, (int, np.integer)) and not isinstance(count, (bool, np.bool_)), (
            f"{name}.terms returned {count!r} ({type(count).__name__}), not an int"
        )
        assert count >= 0, f"{name}.terms returned {count!r}, not >= 0"
        assert terms(observations) == count, f"{name}.terms gave two answers for the same observations"
    image = _observation_image(observations)
    scored = start.copy()
    buffer = np.full(n, np.nan)
    try:
        first = model.log_likelihood(scored, observations, out=buffer)
    except TypeError as error:
        raise AssertionError(
            f"{name}.log_likelihood(poses, observations, out=buffer) raised TypeError: {error}; "
            "the filter passes `out=` (it may be ignored, the returned array is used)"
        ) from error
    except Exception as error:
        raise AssertionError(
            f"{name}.check accepted the observations but log_likelihood raised {type(error).__name__}: {error}"
        ) from error
    first = np.array(first, copy=True)
    assert first.shape == (n,), f"{name}.log_likelihood returned shape {first.shape} for {n} poses; must be ({n},)"
    assert first.dtype.kind == "f", f"{name}.log_likelihood returned dtype {first.dtype}; must be floats"
    bad = np.isnan(first) | np.isposinf(first) | (np.isneginf(first) & (not allow_neg_inf))
    if bad.any():
        i = int(np.argmax(bad))
        raise AssertionError(
            f"{name}.log_likelihood gave {float(first[i])!r} for poses[{i}] = {start[i].tolist()!r} "
            f"({int(bad.sum())} of {n}); must be finite" + (" or -inf" if allow_neg_inf else "")
        )
    limit = _bound_of(bound, observations)
    if limit is not None:
        above = first > limit
        if above.any():
            i = int(np.argmax(above))
            raise AssertionError(
                f"{name}.log_likelihood gave {float(first[i])!r} for poses[{i}] = "
                f"{start[i].tolist()!r}, above the bound {limit!r}"
            )
    difference = _array_difference("poses", start, scored)
    if difference:
        raise AssertionError(f"{name}.log_likelihood changed its input: {difference}")
    after = _observation_image(observations)
    for (label, a), (_, b) in zip(image, after):
        difference = _array_difference(label, a, b) if label != "view" else (None if a == b else f"view: {a} -> {b}")
        if difference:
            raise AssertionError(f"{name}.log_likelihood changed the observations: {difference}")
    try:
        again = np.array(model.log_likelihood(start.copy(), observations), copy=True)
        third = np.array(model.log_likelihood(start.copy(), observations, out=np.full(n, np.inf)), copy=True)
    except Exception as error:
        raise AssertionError(
            f"{name}.log_likelihood raised {type(error).__name__} on the same input the second time: {error}"
        ) from error
    for label, values in (("without out", again), ("with another out buffer", third)):
        difference = _array_difference("log_likelihood", first, values)
        if difference:
            raise AssertionError(
                f"{name}.log_likelihood gave different results for the same input ({label}): {difference}"
            )
    return True


def _far_rows(field: Field) -> st.SearchStrategy:
    """Poses a filter may hold far off the carpet (set_particles takes |x|, |y| up to 1000 m)."""
    corner = st.sampled_from([-LARGEST_COORDINATE, LARGEST_COORDINATE, 0.0])
    return st.lists(
        st.tuples(
            st.one_of(corner, st.floats(-LARGEST_COORDINATE, LARGEST_COORDINATE)),
            st.one_of(corner, st.floats(-LARGEST_COORDINATE, LARGEST_COORDINATE)),
            st.floats(-math.pi, math.pi, exclude_min=True),
        ),
        max_size=3,
    )


def check_sensor_model(
    model: SensorModel,
    field: Field,
    *,
    n: int | tuple[int, int] = (1, 64),
    frames: st.SearchStrategy | None = None,
    hostile: st.SearchStrategy | None = None,
    bound: float | Callable[[Observations], float] | None = None,
    allow_neg_inf: bool = False,
    max_examples: int = 20,
    shrink: bool | None = None,
) -> ContractReport:
    """Check a sensor model against the contract the filter relies on, on examples hypothesis draws.

    Each example runs `assert_sensor_contract` on particles on the carpet (sometimes with a few far off it)
    for a frame from `observations` and one from `hostile`. Runs its own hypothesis search: call it from a
    plain test, not inside ``@given``.

    Parameters
    ----------
    model : sensor model
        Anything with `check(observations)` and `log_likelihood(poses, observations, out=None)`, optionally
        `terms(observations)`.
    field : field.Field
        The field the model scores on: particles lie on its carpet, detections are of its landmark types.
    n : int or (int, int), optional
        Particles per example (default 1 to 64).
    frames : hypothesis strategy of Observations, optional
        Frames the model should score (default: up to 8 detections with and without their own noise, up to 16
        line points, sometimes a camera view). The model may refuse some, not all.
    hostile : hypothesis strategy of Observations, optional
        Frames to score or refuse cleanly (default `edge_observations(field)`).
    bound : float or callable, optional
        The largest log-likelihood accepted, or a function of the observations giving it (default: any finite
        value).
    allow_neg_inf : bool, optional
        Accept -inf log-likelihoods (default False).
    max_examples : int, optional
        Examples to run (default 20).
    shrink : bool, optional
        Whether hypothesis shrinks a failing example to a small one (slower) or reports the first it finds;
        default None: as the loaded hypothesis profile's phases say (all of them, unless a profile leaves
        shrinking out).

    Returns
    -------
    ContractReport
        How many frames were accepted and refused.

    Raises
    ------
    AssertionError
        On the first property that fails (after hypothesis has shrunk the example), or when the model refuses
        every frame from `observations`.
    """
    report = ContractReport()
    good = (
        frames
        if frames is not None
        else observations(field, max_detections=8, with_sigmas=True, max_line_points=16, with_view=True)
    )
    bad_frames = edge_observations(field) if hostile is None else hostile

    def test(poses, far, frame, bad):
        report.examples += 1
        rows = np.concatenate([poses, np.array(far, dtype=np.float64).reshape(-1, 3)]) if far else poses
        if assert_sensor_contract(model, rows, frame, bound=bound, allow_neg_inf=allow_neg_inf):
            report.accepted += 1
        else:
            report.refused += 1
        if assert_sensor_contract(model, rows, bad, bound=bound, allow_neg_inf=allow_neg_inf):
            report.hostile_accepted += 1
        else:
            report.hostile_refused += 1

    _run(
        test, max_examples, dict(poses=pose_arrays(field, n), far=_far_rows(field), frame=good, bad=bad_frames), shrink
    )
    assert report.accepted > 0, (
        f"{_name(model)} refused all {report.refused} frames drawn: give `frames=` a strategy of the frames it takes"
    )
    return report
