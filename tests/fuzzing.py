"""The fuzz suite's harness: hostile values, state snapshots, and the check every fuzzed call goes through.

Each fuzz target (`tests/fuzz_targets.py`) calls public entry points with generated arguments through `attempt`:

- a call that is refused must raise `ValueError` or `TypeError` (the library's one error family), and leave the
  object exactly as it was: `snapshot` before and after must be equal, the random generator's state included;
- a call that is accepted must leave a sane state (`check_filter`: finite poses, wrapped headings, weights that
  sum to one, no NaN anywhere);
- any other exception is a failure, and so is a crash of the process: `tests/fuzz_run.py` runs the targets in a
  child process and reports the case that was running when it died (`record_case` writes it down first).
"""

from __future__ import annotations

import math
import os
import types
from collections import Counter, deque

import numpy as np
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp
from numba.core.dispatcher import Dispatcher

ERRORS = (ValueError, TypeError)

# Counts per target: cases run, calls accepted, calls refused (read by the runner).
COUNTS: Counter = Counter()
_CASE_FILE: str | None = os.environ.get("ROBOCUP_MCL_FUZZ_CASE_FILE")


def record_case(target: str, description) -> None:
    """Count one case of `target` and, in a child process of the runner, write it down before it runs: if the
    process dies, the runner reports this case."""
    COUNTS[(target, "cases")] += 1
    if _CASE_FILE:
        with np.printoptions(threshold=50, precision=17):
            text = f"{target}: {description!r}"[:4000]
        with open(_CASE_FILE, "w") as f:
            f.write(text)


# -- hostile values --------------------------------------------------------------------------------------------
SPECIAL = [
    0.0,
    -0.0,
    5e-324,
    1e-300,
    1e-200,
    1e-160,
    1e-12,
    1e-9,
    1e-6,
    1e-3,
    0.01,
    0.1,
    0.5,
    1.0,
    2.0,
    math.pi,
    2 * math.pi,
    10.0,
    99.0,
    100.0,
    100.5,
    1e3,
    1e6,
    1e12,
    1e100,
    1e300,
    1.7976931348623157e308,
    math.nan,
    math.inf,
]
SPECIAL = SPECIAL + [-v for v in SPECIAL]


def numbers() -> st.SearchStrategy:
    """Floats anywhere (NaN, ±inf, subnormals, the largest), often the special ones, and huge integers."""
    return st.one_of(st.sampled_from(SPECIAL), st.floats(), st.floats(-20, 20), st.integers(-(10**20), 10**20))


def sane(low: float = -5.0, high: float = 5.0) -> st.SearchStrategy:
    return st.floats(low, high, allow_nan=False, allow_infinity=False)


def junk() -> st.SearchStrategy:
    """Values of the wrong kind: None, strings, booleans, containers, objects."""
    return st.one_of(
        st.none(),
        st.text(max_size=3),
        st.booleans(),
        st.just(object()),
        st.just([]),
        st.just({}),
        st.just(b"\x00"),
        st.just(np.array([[1.0, 2.0], [3.0, 4.0]])),
    )


def number_or_junk() -> st.SearchStrategy:
    return st.one_of(numbers(), numbers(), numbers(), junk())


def triples(scale: float = 1.0) -> st.SearchStrategy:
    """(x, y, θ)-like values: mostly three numbers, sometimes sane ones, sometimes the wrong shape or kind."""
    sane3 = st.tuples(sane(-scale, scale), sane(-scale, scale), sane(-scale, scale))
    return st.one_of(
        sane3,
        sane3,
        st.tuples(numbers(), numbers(), numbers()),
        st.lists(numbers(), max_size=5),
        hnp.arrays(np.float64, st.sampled_from([(3,), (1, 3), (2, 3), (3, 1), (0,)]), elements=st.floats()),
        junk(),
    )


# -- state -----------------------------------------------------------------------------------------------------
# Buffers a filter overwrites before reading (scratch), caches derived from what is compared, and handles:
# not state. Everything else an object holds is compared bit for bit.
SCRATCH = frozenset(
    {
        "_log_likelihood",
        "_previous",
        "_capture_poses",
        "_trig",
        "_variates",
        "_state_scratch",
        "_local_histograms",
        "_rng_handle",
        "_state_rows",
        "_compiled_sensor_of",
        "_bounded_of",
        "_bounded",
        "_compiled_sensor",
        "_cumulative_rows",
        "_thread_scope",
        # Localizer.counts records refused frames too ("observation older than history")
        "counts",
    }
)


def _array_key(array: np.ndarray):
    return ("array", array.dtype.str, array.shape, np.ascontiguousarray(array).tobytes())


def snapshot(obj, _seen=None):
    """A comparable, bit-exact image of everything `obj` holds (floats by their bits, so NaN equals NaN)."""
    seen = set() if _seen is None else _seen
    if obj is None or isinstance(obj, (bool, int, str, bytes)):
        return obj
    if isinstance(obj, float):
        return ("float", np.float64(obj).tobytes())
    if isinstance(obj, np.ndarray):
        return _array_key(obj)
    if isinstance(obj, np.generic):
        return ("scalar", obj.dtype.str, obj.tobytes())
    if isinstance(obj, np.random.Generator):
        return ("generator", repr(obj.bit_generator.state))
    if isinstance(
        obj, (types.FunctionType, types.BuiltinFunctionType, types.MethodType, types.ModuleType, type, Dispatcher)
    ):
        return ("callable", getattr(obj, "__qualname__", repr(obj)))
    params = getattr(type(obj), "__dataclass_params__", None)
    if params is not None and params.frozen:
        return ("frozen", type(obj).__qualname__, id(obj))  # cannot be changed (its fields are read-only)
    if id(obj) in seen:
        return ("seen", type(obj).__qualname__)
    seen.add(id(obj))
    if isinstance(obj, (list, tuple, deque)):
        return (type(obj).__name__, tuple(snapshot(v, seen) for v in obj))
    if isinstance(obj, dict):
        return ("dict", tuple(sorted(((repr(k), snapshot(v, seen)) for k, v in obj.items()), key=lambda kv: kv[0])))
    if isinstance(obj, (set, frozenset)):
        return ("set", tuple(sorted(repr(v) for v in obj)))
    state = {}
    if hasattr(obj, "__dict__"):
        state.update(vars(obj))
    for name in getattr(type(obj), "__slots__", ()):
        if hasattr(obj, name):
            state[name] = getattr(obj, name)
    if not state:
        return ("opaque", type(obj).__qualname__, repr(obj)[:200])
    if state.get("_summary_valid") is False:
        state.pop("_summary", None)  # the histograms are refilled before they are read
    return (type(obj).__qualname__, tuple(sorted((k, snapshot(v, seen)) for k, v in state.items() if k not in SCRATCH)))


def first_difference(a, b, path: str = "object") -> str:
    """Where two snapshots differ (for the failure message)."""
    if isinstance(a, tuple) and isinstance(b, tuple) and len(a) == len(b):
        for i, (x, y) in enumerate(zip(a, b)):
            if x != y:
                named = (
                    isinstance(x, tuple)
                    and len(x) == 2
                    and isinstance(x[0], str)
                    and isinstance(y, tuple)
                    and len(y) == 2
                    and x[0] == y[0]
                    and not x[0].isupper()
                )
                if named and isinstance(x[1], tuple):
                    return first_difference(x[1], y[1], f"{path}.{x[0]}")
                return first_difference(x, y, path if named else f"{path}[{i}]")
    return f"{path}: {str(a)[:100]} -> {str(b)[:100]}"


def check_filter(pf) -> None:
    """An accepted call left a sane filter: finite poses with headings in (-π, π], weights summing to one."""
    poses = pf.poses
    assert np.isfinite(poses).all(), "non-finite poses"
    assert (np.abs(poses[:, 2]) <= math.pi).all(), (
        f"unwrapped headings, e.g. {poses[np.argmax(np.abs(poses[:, 2])), 2]!r}"
    )
    weights = np.asarray(pf.weights)
    assert np.isfinite(weights).all() and (weights >= 0).all(), "weights not finite and >= 0"
    assert abs(weights.sum() - 1.0) < 1e-9, f"weights sum to {weights.sum()!r}"
    log_weights = np.asarray(pf.log_weights)
    assert not np.isnan(log_weights).any() and not np.isposinf(log_weights).any(), "NaN or +inf log-weights"
    state = pf.motion_state
    if state is not None:
        assert np.isfinite(state).all(), "non-finite motion state"


def check_estimate(pf) -> None:
    estimate = pf.estimate()
    assert np.isfinite(estimate.pose).all() and np.isfinite(estimate.covariance).all(), "non-finite estimate"
    assert abs(estimate.pose[2]) <= math.pi, "unwrapped estimate heading"
    assert 0.0 <= estimate.weight <= 1.0 + 1e-9, f"estimate weight {estimate.weight!r}"
    entropy = pf.entropy()
    for value, bound in zip((entropy.position, entropy.orientation), pf.entropy_bounds):
        assert -1e-9 <= value <= bound + 1e-9, f"entropy {value!r} outside [0, {bound!r}]"


def attempt(target: str, owner, call, check=None) -> bool:
    """Run `call()` on `owner` (an object, or None for a constructor). Refused (ValueError/TypeError): `owner`
    must be unchanged; accepted: `check(owner)` must pass. Returns whether it was accepted. Any other exception
    propagates and fails the case."""
    before = snapshot(owner) if owner is not None else None
    try:
        call()
    except ERRORS as error:
        COUNTS[(target, "refused")] += 1
        assert str(error), f"{type(error).__name__} without a message"
        if owner is not None:
            after = snapshot(owner)
            if after != before:
                raise AssertionError(
                    f"refused ({type(error).__name__}: {error}) but changed {first_difference(before, after)}"
                ) from error
        return False
    COUNTS[(target, "accepted")] += 1
    if check is not None and owner is not None:
        check(owner)
    return True
