"""Models registered by name (in code or through entry points) and checked together (`check_registered`)."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

from field import Field, spl
from mcl.tools.testing.contracts import ContractReport, check_motion_model, check_sensor_model
from mcl.tools.testing.invariants import assert_same_seed_same_run
from mcl.tools.testing.strategies import REFUSALS, _preset
from motion_models import FootstepEvent, MotionInput
from proprioception.collision import NO_COLLISION
from sensing import Observations

# A team's models join the contract checks the library's own models go through: registered in the process
# (`register_motion_model`, `register_sensor_model`, e.g. in a conftest.py) or declared by an installed package
# as an entry point, so that the library's own contract tests (tests/test_contracts.py, run from a clone in
# the team's environment) check them too:
#
#     [project.entry-points."robocup_mcl.motion_models"]
#     our-odometry = "our_robot.localization:OurOdometry"          # called with no arguments
#     [project.entry-points."robocup_mcl.sensor_models"]
#     our-goals = "our_robot.localization:OurGoalModel"            # called with the field
ENTRY_POINT_GROUPS = {"motion": "robocup_mcl.motion_models", "sensor": "robocup_mcl.sensor_models"}
MODEL_KINDS = tuple(ENTRY_POINT_GROUPS)


@dataclass(frozen=True)
class RegisteredModel:
    """A model that `check_registered` runs through the contract checks.

    Attributes
    ----------
    name : str
        Its name in reports and test ids.
    kind : str
        "motion" or "sensor".
    make : callable
        Builds the model: with no arguments for a motion model, with the `field.Field` for a sensor model.
    refused : tuple of MotionInput
        Inputs a motion model must refuse (passed to `check_motion_model`).
    source : str
        "registered" (in this process) or "entry point <value>" (declared by an installed package).
    """

    name: str
    kind: str
    make: Callable[..., Any]
    refused: tuple = ()
    source: str = "registered"

    def build(self, field: Field) -> Any:
        """The model, built for `field` (a sensor model) or without it (a motion model).

        Parameters
        ----------
        field : field.Field
            Passed to `make` for a sensor model; unused for a motion model.

        Returns
        -------
        MotionModel or SensorModel
            What `make` returns.
        """
        return self.make(field) if self.kind == "sensor" else self.make()


_REGISTERED: dict[tuple[str, str], RegisteredModel] = {}


def _register(kind: str, name, make, refused: Sequence[MotionInput] = ()) -> RegisteredModel:
    if not isinstance(name, str) or not name.strip():
        raise ValueError(f"a registered model needs a non-empty name, not {name!r}")
    if not callable(make):
        raise TypeError(f"register a callable that builds the {kind} model, not {type(make).__name__}")
    refused = tuple(refused)
    if not all(isinstance(u, MotionInput) for u in refused):
        raise TypeError("refused= takes MotionInput values")
    if (kind, name) in _REGISTERED:
        raise ValueError(f"a {kind} model named {name!r} is already registered; unregister it first")
    entry = RegisteredModel(name, kind, make, refused)
    _REGISTERED[(kind, name)] = entry
    return entry


def register_motion_model(
    name: str, make: Callable[[], Any], *, refused: Sequence[MotionInput] = ()
) -> RegisteredModel:
    """Register a motion model for `check_registered` (and the library's contract tests run in this process).

    Parameters
    ----------
    name : str
        A name unique among registered motion models.
    make : callable
        Called with no arguments, returns the model (a class works).
    refused : sequence of MotionInput, optional
        Inputs the model must refuse.

    Returns
    -------
    RegisteredModel

    Raises
    ------
    ValueError
        An empty name, or a name already registered (nothing is registered then).
    TypeError
        `make` is not callable, or `refused` holds something other than MotionInput values.
    """
    return _register("motion", name, make, refused)


def register_sensor_model(name: str, make: Callable[[Field], Any]) -> RegisteredModel:
    """Register a sensor model for `check_registered`: `make(field)` returns the model (a class works).

    Parameters
    ----------
    name : str
        A name unique among registered sensor models.
    make : callable
        Called with the `field.Field`, returns the model (a class works).

    Returns
    -------
    RegisteredModel

    Raises
    ------
    ValueError
        An empty name, or a name already registered (nothing is registered then).
    TypeError
        `make` is not callable.
    """
    return _register("sensor", name, make)


def unregister(kind: str, name: str) -> None:
    """Take a model registered in this process off the list (KeyError when there is none by that name).

    Parameters
    ----------
    kind : str
        "motion" or "sensor".
    name : str
        The name it was registered under.

    Raises
    ------
    ValueError
        If `kind` is neither "motion" nor "sensor".
    KeyError
        If no model of that kind is registered in this process under `name` (entry points cannot be
        unregistered).
    """
    if kind not in MODEL_KINDS:
        raise ValueError(f"kind must be one of {MODEL_KINDS}, not {kind!r}")
    del _REGISTERED[(kind, name)]


def _entry_points(kind: str) -> list[RegisteredModel]:
    from importlib.metadata import entry_points

    found = []
    for point in entry_points(group=ENTRY_POINT_GROUPS[kind]):

        def make(*args, _point=point):
            return _point.load()(*args)

        found.append(RegisteredModel(point.name, kind, make, (), f"entry point {point.value}"))
    return found


def registered_models(kind: str | None = None) -> list[RegisteredModel]:
    """The models registered in this process and declared as entry points by installed packages, in that
    order, motion models first; `kind` ("motion" or "sensor") keeps one kind. Entry points are loaded only when
    a model is built.

    Parameters
    ----------
    kind : str or None, optional
        "motion" or "sensor" to keep one kind; None (the default) for both.

    Returns
    -------
    list of RegisteredModel
        The models, motion models first; of each kind, those registered in this process, then the entry points.

    Raises
    ------
    ValueError
        If `kind` is neither None, "motion" nor "sensor".
    """
    if kind is not None and kind not in MODEL_KINDS:
        raise ValueError(f"kind must be one of {MODEL_KINDS} or None, not {kind!r}")
    kinds = MODEL_KINDS if kind is None else (kind,)
    return [entry for k in kinds for entry in [e for (ek, _), e in _REGISTERED.items() if ek == k] + _entry_points(k)]


@dataclass
class RegisteredReport:
    """What `check_registered` found for one model.

    Attributes
    ----------
    model : RegisteredModel
    contract : ContractReport
        The contract check's counts.
    fast_path : dict
        `mcl.contracts.fast_path` for the model beside the library's reference partner (a velocity-linear
        motion model for a sensor model, a landmark sensor model for a motion model): whether it moves, or is
        scored, inside the filter's fused compiled step.
    same_run : bool
        A filter with the model gave the same run twice from the same seed (checked; False is never returned,
        a difference raises).
    """

    model: RegisteredModel
    contract: ContractReport
    fast_path: dict
    same_run: bool = True


def check_registered(
    field: Field | None = None, *, kind: str | None = None, max_examples: int = 20, strict: bool = True
) -> list[RegisteredReport]:
    """Run every registered model (see `registered_models`) through the contract checks the library's own
    models pass: `check_motion_model` (shapes, finite and wrapped poses, refusals that change nothing, same
    seed same result) or `check_sensor_model`, a short filter run from the same seed twice, and which part of
    the fused fast path the model reaches.

    Parameters
    ----------
    field : field.Field, optional
        Default `field.spl()`.
    kind : str, optional
        Check only "motion" or only "sensor" models.
    max_examples : int, optional
        Examples per contract check (default 20).
    strict : bool, optional
        Passed to `check_motion_model` (default True: `predict` refuses what `check` refuses).

    Returns
    -------
    list of RegisteredReport
        One per model, in `registered_models` order (empty when none is registered).

    Raises
    ------
    AssertionError
        Naming the model that broke a contract, and how.
    """
    from mcl.contracts import fast_path
    from mcl.filter import ParticleFilter
    from motion_models import VelocityLinear
    from sensing import LandmarkSensorModel

    field = _preset(spl) if field is None else field
    reports = []
    for entry in registered_models(kind):
        try:
            model = entry.build(field)
        except Exception as error:
            raise AssertionError(
                f"registered {entry.kind} model {entry.name!r} ({entry.source}) could not be "
                f"built: {type(error).__name__}: {error}"
            ) from error
        try:
            if entry.kind == "motion":
                contract = check_motion_model(
                    model, field, refused=entry.refused, strict=strict, max_examples=max_examples
                )
                motion, sensor = model, LandmarkSensorModel(field)
                u = _accepted_input(model)
            else:
                contract = check_sensor_model(model, field, max_examples=max_examples)
                motion, sensor = VelocityLinear(), model
                u = MotionInput(dt=0.01, command=(0.2, 0.0, 0.1), collision=NO_COLLISION)
            frame = Observations.from_arrays(["goalpost", "T"], [3.0, 2.0], [0.3, -0.4])
            steps = [(u, None), (u, frame), (u, frame)] if u is not None else []
            assert_same_seed_same_run(lambda: ParticleFilter(field, motion, sensor, n_particles=64, seed=3), steps)
        except Exception as error:
            failures = _assertions(error)
            if not failures:
                raise
            more = f" (and {len(failures) - 1} other failures)" if len(failures) > 1 else ""
            raise AssertionError(
                f"registered {entry.kind} model {entry.name!r} ({entry.source}): {failures[0]}{more}"
            ) from error
        reports.append(RegisteredReport(entry, contract, fast_path(motion, sensor)))
    return reports


def _assertions(error: BaseException) -> list[AssertionError]:
    """The assertion failures in `error`: itself, or those of an exception group (hypothesis raises one when it
    finds several distinct failures); empty when any part is not an assertion failure."""
    if isinstance(error, AssertionError):
        return [error]
    parts = getattr(error, "exceptions", None)
    if not parts:
        return []
    found = [_assertions(part) for part in parts]
    return [] if not all(found) else [failure for group in found for failure in group]


_PROBES = (
    MotionInput(dt=0.01, command=(0.2, 0.0, 0.1), collision=NO_COLLISION),
    MotionInput(dt=0.01, odometry=(0.002, 0.0, 0.001), collision=NO_COLLISION),
    MotionInput(
        dt=0.01,
        footstep=FootstepEvent(
            support=1,
            commanded=(0.04, 0.0, 0.1),
            sensor=(0.04, 0.0, 0.1),
            duration=0.3,
            previous_sensor=(0.04, 0.0, 0.1),
            previous_duration=0.3,
        ),
        collision=NO_COLLISION,
    ),
)


def _accepted_input(model) -> MotionInput | None:
    """A plain walking input the motion model accepts (a command, odometry or a footstep), or None."""
    for u in _PROBES:
        try:
            model.check(u)
        except REFUSALS:
            continue
        return u
    return None
