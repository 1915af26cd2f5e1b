"""`AdaptiveMotion`: Hoffmann's adaptive motion model, five mobility states driven by collision percepts.

    from motion_models import AdaptiveMotion, MotionInput
    from proprioception.collision import CollisionDetector, NO_COLLISION

    model = AdaptiveMotion()                                   # documented defaults, see below
    pf = ParticleFilter(field, model, sensor, n_particles=100)  # the filter keeps each particle's state
    percept = detector.update(joint_command, joint_reading, phase, walk_command)
    pf.predict(MotionInput(dt=0.01, command=(0.2, 0.0, 0.0), collision=percept))
    model.state_belief(pf.motion_state, pf.weights)            # (5,): free, slippage, hindrance, pushed, stopped

The effective velocity is m_eff = m + ε_odo + ε_col (Hoffmann eq. 11–13). ε_odo is the odometry error of a
freely walking robot, eq. 10 with β fitted to free walking (`robocup-mcl fit adaptive`; its heading term is
larger than `VelocityLinear`'s: a calibrated robot's turn bias); ε_col depends on the mobility state (section 3.1):

    free        m unchanged                                                   (ε_col = 0)
    slippage    v' = v·rand(β1, 1),  ω' = ω + β2·rand(-1, 1)                   (eq. 14–15)
    hindrance   v' = v·rand(β3, 1),  ω' = ω·rand(β4, 1)                        (eq. 16–17)
    pushed      displaced by d = β5·rand(0, 1) toward α = rand(-π, π),
                turned by β6·rand(-1, 1)                                       (eq. 18–22)
    stopped     v' = 0,  ω' = (|v|/w)·c(z_c)·β_turn·rand(0, 1)                 (eq. 23, 25–26)
                or ω' = β7·rand(-1, 1) when no side is known                   (eq. 24)

with c(z_c) = +1 for a collision on the left, -1 on the right, 0 on both (`CollisionPercept.side`). Translations
are in the robot frame, so the model commutes with rotating the world. ε_odo is eq. 10 on the effective
speeds: a stopped robot does not translate at all.

Jump-Markov particle filter. Each particle carries its own mobility state (`particle_state`, kept by the
filter through resampling) so that landmark observations weigh "it was pushed" against "it walked on". At each
step a particle's state moves along a Markov chain whose transition probabilities depend on the collision
percept: P = expm(Q·dt) for a generator Q (rates per second, `MobilityTransitions`), which keeps the chain the
same at any step rate and makes every row a probability distribution. No collision returns toward free; a
collision leads into hindrance, pushed or slippage; collisions at high frequency (the percept's `rate` at or
above `frequent_rate`) lead into stopped and mostly keep the robot there (section 3.1, Fig. 1; an episode
ends there at fitted rates, since the detector's window outlasts the contact).

The rand() of eq. 14–26 are drawn when a particle leaves free (a collision episode starts) and held until it is
free again (`redraw="episode"`, the default): a collision moves a robot consistently for its duration (one push
direction, one turning rate), also when the particle passes from hindrance to stopped.
Drawn afresh every step (`redraw="step"`), the perturbations average out over the hundred steps of a two-second
collision and the cloud hardly spreads; `robocup-mcl demo collision` measures both.

Units and defaults. SI throughout: β2, β6, β7 in rad/s and β5 in m/s are rates (the paper's per-step values at
8 ms are ambiguous, see `VelocityLinear`), β1, β3, β4, β_turn are shares. β1..β7 and β_turn are fitted from
training logs (`robocup-mcl fit adaptive`, results/adaptive_fit.json, rounded to three decimals): each uniform
range covers 95 % of the per-episode rates that motion capture measured on 40 simulated robots whose physics
is drawn beyond these ranges; β7 = 0 because the training robots held on both sides stood still. The same
command fits the free-walking noise (eq. 10's β, so that over 5 s of free walking the model's 95 % interval
holds 95 % of the training robots' errors) and the rates at which an episode ends while the percept still says
"frequent" (maximum likelihood: ends counted over the time spent in the state; the paper's chain has no exit
there, and the detector's window outlasts the contact by up to half a second). The other transition rates and
`frequent_rate` are documented settings, not fitted.
`stop_creep` > 0 is a variant (the robot walks on while it pivots about the held foot), 0 by default.

Update rate. The chain (P = expm(Q·dt)) and the episode's perturbations (rates held for the episode) do not
depend on the update rate. Eq. 10's odometry noise, drawn afresh every step, would: by default
(`noise_rate="per_second"`) its half-widths are scaled by sqrt(REFERENCE_DT / dt), REFERENCE_DT = 0.01 s (the
loop `odometry` was fitted at; `motion_models.base.noise_rate_factor`), so they spread a free walk the same per
second at any rate, and are eq. 10's exactly at 100 Hz; `noise_rate="per_step"` is eq. 10 as written. With
`redraw="step"` the perturbations are drawn afresh every step and average out faster at a higher rate: that
variant is not rate-independent.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, field, fields
from typing import TYPE_CHECKING, ClassVar

import numba
import numpy as np

from field.moved import moved_names
from numerics.random import PCG64_STEPS, bit_generator_handle, deferred_uniform, draw_rows_deferring
from numerics.trig import sincos, wrap

from .base import MAX_NOISE_PARAMETER, MotionInput, check_noise_rate, check_nonnegative, check_poses, noise_rate_factor
from .kernels import DRAWS
from .percepts import CollisionPercept

# The numpy twins moved to the package's `reference` module; their old names still work, with a warning.
__getattr__ = moved_names(__name__, {"adaptive_move_reference": "motion_models.reference.adaptive_move"})

FREE, SLIPPAGE, HINDRANCE, PUSHED, STOPPED = range(5)
STATES = ("free", "slippage", "hindrance", "pushed", "stopped")
CONDITIONS = ("quiet", "collision", "frequent")
STATE_COLUMNS = 4  # per particle: mobility state, then the three rand() values of its episode
VARIATES = 7  # per particle and step: transition, three fresh episode values, three odometry noise
MAX_ODOMETRY_SPEED = 1000.0  # m/s and rad/s: the most odometry over dt may imply (a shorter step is a clock glitch)
_CUMULATIVE_MEMO = 64  # (condition, dt) pairs an AdaptiveMotion keeps the cumulative transition rows of


def _rates(pairs: dict[tuple[str, str], float]) -> tuple[tuple[str, str, float], ...]:
    return tuple((a, b, float(rate)) for (a, b), rate in pairs.items())


@dataclass(frozen=True)
class MobilityTransitions:
    """Transition rates between mobility states [1/s], one set per percept condition.

    Each entry is (from, to, rate); a state's probability of staying is what its rates leave. As in the paper,
    only collision events lead away from free: add quiet ("free", ...) rates to stand for collisions the
    detector misses (each particle then leaves free that often, and the cloud grows outliers).

    Parameters
    ----------
    quiet : tuple of (str, str, float)
        No collision detected within the detector's recent window (percept rate 0).
    collision : tuple of (str, str, float)
        Collisions detected recently, but not at high frequency.
    frequent : tuple of (str, str, float)
        Collisions at high frequency (percept rate >= `AdaptiveMotion.frequent_rate`).

    Raises
    ------
    ValueError
        If an entry is not (from, to, rate) with two different names of `STATES` and a finite rate >= 0.
    """

    quiet: tuple[tuple[str, str, float], ...] = _rates(
        {("slippage", "free"): 3.0, ("hindrance", "free"): 4.0, ("pushed", "free"): 5.0, ("stopped", "free"): 4.0}
    )
    collision: tuple[tuple[str, str, float], ...] = _rates(
        {
            ("free", "slippage"): 2.0,
            ("free", "hindrance"): 4.0,
            ("free", "pushed"): 2.0,
            ("slippage", "hindrance"): 1.0,
            ("pushed", "hindrance"): 1.0,
            ("hindrance", "stopped"): 1.0,
            ("stopped", "hindrance"): 1.0,
            ("stopped", "free"): 5.0,
        }
    )
    frequent: tuple[tuple[str, str, float], ...] = _rates(
        {
            ("free", "hindrance"): 4.0,
            ("free", "pushed"): 1.0,
            ("free", "slippage"): 1.0,
            ("free", "stopped"): 2.0,
            ("slippage", "stopped"): 3.0,
            ("hindrance", "stopped"): 3.0,
            ("pushed", "stopped"): 3.0,
            # Episode ends while the percept still says "frequent" (fitted: results/adaptive_fit.json).
            ("hindrance", "free"): 0.911,
            ("pushed", "free"): 2.486,
            ("stopped", "free"): 0.641,
        }
    )

    def __post_init__(self) -> None:
        for condition in CONDITIONS:
            for entry in getattr(self, condition):
                if len(entry) != 3:
                    raise ValueError(f"{condition} entry {entry!r} must be (from, to, rate)")
                source, target, rate = entry
                for name in (source, target):
                    if name not in STATES:
                        raise ValueError(f"{condition} entry {entry!r}: {name!r} is not one of {STATES}")
                if source == target:
                    raise ValueError(f"{condition} entry {entry!r}: a rate must lead to another state")
                if not (isinstance(rate, (int, float)) and math.isfinite(rate) and rate >= 0):
                    raise ValueError(f"{condition} entry {entry!r}: rate must be finite and >= 0")

    def generator(self, condition: str) -> np.ndarray:
        """The rate matrix Q (5, 5) of a condition: off-diagonal rates, rows summing to zero.

        Parameters
        ----------
        condition : str
            One of `CONDITIONS`: "quiet", "collision" or "frequent".

        Returns
        -------
        numpy.ndarray
            (5, 5) rates [1/s], rows and columns in the order of `STATES`.

        Raises
        ------
        ValueError
            If the condition is unknown.
        """
        if condition not in CONDITIONS:
            raise ValueError(f"condition = {condition!r} must be one of {CONDITIONS}")
        q = np.zeros((5, 5))
        for source, target, rate in getattr(self, condition):
            q[STATES.index(source), STATES.index(target)] += rate
        q[np.diag_indices(5)] = -q.sum(axis=1)
        return q

    def matrix(self, condition: str, dt: float) -> np.ndarray:
        """Transition probabilities over dt seconds: P = expm(Q·dt), rows summing to one.

        Parameters
        ----------
        condition : str
            One of `CONDITIONS`.
        dt : float
            The time step [s].

        Returns
        -------
        numpy.ndarray
            (5, 5) probabilities (a copy), rows and columns in the order of `STATES`.
        """
        return _transition_matrix(self, condition, float(dt)).copy()


@functools.lru_cache(maxsize=64)
def _transition_matrix(transitions: MobilityTransitions, condition: str, dt: float) -> np.ndarray:
    import scipy.linalg  # here, not at module level: `import mcl` does not load scipy.linalg

    p = scipy.linalg.expm(transitions.generator(condition) * dt)
    p = np.clip(p, 0.0, None)
    return p / p.sum(axis=1, keepdims=True)


@functools.lru_cache(maxsize=64)
def _cumulative(transitions: MobilityTransitions, condition: str, dt: float) -> np.ndarray:
    cumulative = np.cumsum(_transition_matrix(transitions, condition, dt), axis=1)
    cumulative[:, -1] = 1.0  # rounding must never let a uniform variate fall past the last state
    cumulative.flags.writeable = False
    return cumulative


@dataclass(frozen=True)
class AdaptiveMotion:
    """Hoffmann's adaptive motion model (see the module docstring). Needs `MotionInput.collision`.

    Parameters
    ----------
    beta1 : float, default 0.189
        Slippage: the share of the speed kept at least, in [0, 1) (eq. 14).
    beta2 : float, default 0.651
        Slippage: heading rate error bound [rad/s] (eq. 15).
    beta3 : float, default 0.162
        Hindrance: the share of the speed kept at least, in [0, 1) (eq. 16).
    beta4 : float, default 0.886
        Hindrance: the share of the turn rate kept at least, in [0, 1) (eq. 17).
    beta5 : float, default 0.659
        Pushed: push speed bound [m/s] (eq. 19).
    beta6 : float, default 0.899
        Pushed: heading rate bound [rad/s] (eq. 22).
    beta7 : float, default 0.0
        Stopped without a known side: turn rate bound [rad/s] (eq. 24).
    beta_turn : float, default 1.204
        Stopped: turn toward the collision, share of |v|/w (eq. 25).
    foot_separation : float, default 0.1
        w of eq. 25, the lateral distance between the feet [m], finite and > 0.
    odometry : tuple of float, default (1.24, 1.23, 1.701, 1.701)
        β1..β4 of eq. 10 for free walking, each in [0, `MAX_NOISE_PARAMETER`] (fitted at the 100 Hz loop).
    frequent_rate : float, default 0.25
        The share of the recent second with a collision that counts as "at high frequency", in (0, 1].
    transitions : MobilityTransitions, default MobilityTransitions()
        The transition rates between mobility states.
    redraw : str, default "episode"
        "episode" or "step": when the rand() of eq. 14-26 are drawn.
    stop_creep : float, default 0.0
        Stopped with a known side: the robot pivots about its held foot, so its centre walks on along the
        request at |v|·stop_creep·rand(0, 1), with the same rand() as the turn (the variant "adaptive-pivot" of
        `robocup-mcl demo collision`); 0 is the paper's eq. 23 (v' = 0). Finite and >= 0.
    noise_rate : str, default "per_second"
        How eq. 10's odometry noise depends on the update rate: "per_second", the `odometry` β hold at any rate
        (half-widths times sqrt(0.01 s / dt), exactly eq. 10 at 100 Hz); "per_step", eq. 10 as written
        (`motion_models.base.NOISE_RATES`).

    Raises
    ------
    ValueError
        If a parameter is out of its range.
    """

    beta1: float = 0.189  # slippage: speed kept at least this share (eq. 14)
    beta2: float = 0.651  # rad/s, slippage: heading rate error bound (eq. 15)
    beta3: float = 0.162  # hindrance: speed kept at least this share (eq. 16)
    beta4: float = 0.886  # hindrance: turn rate kept at least this share (eq. 17)
    beta5: float = 0.659  # m/s, pushed: push speed bound (eq. 19)
    beta6: float = 0.899  # rad/s, pushed: heading rate bound (eq. 22)
    beta7: float = 0.0  # rad/s, stopped without a known side: turn rate bound (eq. 24)
    beta_turn: float = 1.204  # stopped: turn toward the collision, share of |v|/w (eq. 25)
    foot_separation: float = 0.1  # m, w of eq. 25: lateral distance between the feet
    odometry: tuple[float, float, float, float] = (1.24, 1.23, 1.701, 1.701)  # β1..β4 of eq. 10, free walking
    frequent_rate: float = 0.25  # share of the recent second with a collision that counts as "at high
    # frequency": a burst each step, or a quarter second of continuous contact
    transitions: MobilityTransitions = field(default_factory=MobilityTransitions)
    redraw: str = "episode"  # "episode" or "step": when the rand() of eq. 14-26 are drawn
    stop_creep: float = 0.0  # stopped: walks on at |v|·stop_creep·rand(0, 1) (0: the paper's eq. 23)
    noise_rate: str = "per_second"  # eq. 10's noise: "per_second" holds at any update rate, "per_step" as written
    if TYPE_CHECKING:  # per-instance memos `_memoize` sets, not fields (ClassVar keeps them out of
        _kernel_params: ClassVar[np.ndarray]  # the dataclass's fields for mypy)
        _cumulative_rows: ClassVar[dict[tuple[str, float], np.ndarray]]
        _scaled_params: ClassVar[dict[float, np.ndarray]]

    def __post_init__(self) -> None:
        check_nonnegative(self, ("beta2", "beta5", "beta6", "beta7", "beta_turn", "stop_creep"))
        for name in ("beta1", "beta3", "beta4"):
            value = getattr(self, name)
            if isinstance(value, bool) or not (isinstance(value, (int, float)) and 0 <= value < 1):
                raise ValueError(f"{name} = {value!r} must be within [0, 1) (Hoffmann eq. 14-17)")
        if not (
            isinstance(self.foot_separation, (int, float))
            and math.isfinite(self.foot_separation)
            and self.foot_separation > 0
        ):
            raise ValueError(f"foot_separation = {self.foot_separation!r} must be finite and > 0")
        odometry = tuple(self.odometry)
        if len(odometry) != 4 or not all(
            isinstance(b, (int, float)) and math.isfinite(b) and 0 <= b <= MAX_NOISE_PARAMETER for b in odometry
        ):
            raise ValueError(
                f"odometry = {self.odometry!r} must be four numbers within [0, {MAX_NOISE_PARAMETER:g}] "
                "(eq. 10's β1..β4)"
            )
        object.__setattr__(self, "odometry", tuple(float(b) for b in odometry))
        if not (isinstance(self.frequent_rate, (int, float)) and 0 < self.frequent_rate <= 1):
            raise ValueError(f"frequent_rate = {self.frequent_rate!r} must be within (0, 1]")
        if not isinstance(self.transitions, MobilityTransitions):
            raise ValueError(f"transitions = {self.transitions!r} must be a MobilityTransitions")
        if self.redraw not in ("episode", "step"):
            raise ValueError(f"redraw = {self.redraw!r} must be 'episode' or 'step'")
        check_noise_rate(self.noise_rate)
        self._memoize()

    def _memoize(self) -> None:
        # Memos of the validated parameters, not fields: what every `predict` hands the kernel unchanged.
        params = np.array(
            [
                self.beta1,
                self.beta2,
                self.beta3,
                self.beta4,
                self.beta5,
                self.beta6,
                self.beta7,
                self.beta_turn,
                self.foot_separation,
                *self.odometry,
                self.stop_creep,
            ],
            dtype=np.float64,
        )
        params.flags.writeable = False
        object.__setattr__(self, "_kernel_params", params)
        object.__setattr__(self, "_cumulative_rows", {})
        object.__setattr__(self, "_scaled_params", {})

    def __getstate__(self) -> dict:
        return {f.name: getattr(self, f.name) for f in fields(self)}

    def __setstate__(self, state: dict) -> None:
        for name, value in state.items():
            object.__setattr__(self, name, value)
        self._memoize()

    # -- the particle state ------------------------------------------------------------------------------
    def particle_state(self, n: int) -> np.ndarray:
        """Fresh per-particle state (n, 4): every particle free.

        Parameters
        ----------
        n : int
            The number of particles.

        Returns
        -------
        numpy.ndarray
            (n, 4) zeros: the state `FREE` and the episode's three rand() values.
        """
        return np.zeros((n, STATE_COLUMNS))

    @staticmethod
    def state_belief(state: np.ndarray, weights: np.ndarray) -> np.ndarray:
        """The belief over the five mobility states: the weighted histogram of the particles' states (5,).

        Parameters
        ----------
        state : numpy.ndarray
            (N, 4) per-particle state, as `particle_state` makes it.
        weights : numpy.ndarray
            (N,) particle weights.

        Returns
        -------
        numpy.ndarray
            (5,) summed weights, in the order of `STATES`.
        """
        return np.bincount(state[:, 0].astype(np.int64), weights=weights, minlength=5)[:5]

    # -- the interface -----------------------------------------------------------------------------------
    def check(self, u: MotionInput) -> None:
        """Raise ValueError unless `predict` can take `u`.

        Parameters
        ----------
        u : MotionInput
            The step's motion: command or odometry over `u.dt` [s], and `u.collision`.

        Raises
        ------
        ValueError
            If `u.collision` is not a `CollisionPercept`, or the odometry over `u.dt` implies more than
            `MAX_ODOMETRY_SPEED`.
        """
        if not isinstance(u.collision, CollisionPercept):
            raise ValueError(
                f"AdaptiveMotion needs MotionInput.collision, a proprioception.collision.CollisionPercept "
                f"(proprioception.collision.NO_COLLISION when nothing was detected); got {u.collision!r}"
            )
        u.displacement()
        self._check_speed(u)

    @staticmethod
    def _check_speed(u: MotionInput) -> None:
        """The model moves by speeds (odometry / dt) and squares them: odometry over a step so short that its
        speed exceeds `MAX_ODOMETRY_SPEED` (a timestamp glitch) is refused, before anything moves, rather than
        turned into infinite poses."""
        if u.command is None and u.odometry is not None and u.dt > 0:
            speed = max(abs(v) for v in u.odometry) / u.dt
            if not speed <= MAX_ODOMETRY_SPEED:
                raise ValueError(
                    f"odometry = {u.odometry!r} over dt = {u.dt!r} s implies {speed:.3g} m/s or rad/s; "
                    f"AdaptiveMotion takes at most {MAX_ODOMETRY_SPEED:g} (a step that short is a "
                    "timestamp glitch)"
                )

    def condition(self, percept: CollisionPercept) -> str:
        """Which transition set applies: "frequent", "collision" or "quiet".

        Parameters
        ----------
        percept : CollisionPercept
            The collision detector's percept for this step.

        Returns
        -------
        str
            "frequent" when `percept.rate` >= `frequent_rate`, "collision" when it is > 0, else "quiet".
        """
        if percept.rate >= self.frequent_rate:
            return "frequent"
        return "collision" if percept.rate > 0 else "quiet"

    def velocities(self, u: MotionInput) -> tuple[float, float, float]:
        """The requested (vx, vy, ω): the command, or the odometry divided by dt.

        Parameters
        ----------
        u : MotionInput
            The step's motion: command or odometry over `u.dt` [s], and `u.collision`.

        Returns
        -------
        tuple of float
            (vx [m/s], vy [m/s], ω [rad/s]); zeros when `u.dt` <= 0 without a command.
        """
        if u.command is not None:
            return u.command
        dx, dy, dtheta = u.displacement()
        if u.dt <= 0:
            return (0.0, 0.0, 0.0)
        return (dx / u.dt, dy / u.dt, dtheta / u.dt)

    def cumulative_transitions(self, condition: str, dt: float) -> np.ndarray:
        """Cumulative rows of expm(Q·dt) for a percept condition (read-only, (5, 5), last column exactly 1),
        computed once per (condition, dt): a filter running at a fixed rate never recomputes the expm.

        Parameters
        ----------
        condition : str
            One of `CONDITIONS`.
        dt : float
            The time step [s].

        Returns
        -------
        numpy.ndarray
            (5, 5) read-only cumulative transition probabilities.
        """
        key = (condition, dt)
        rows = self._cumulative_rows.get(key)
        if rows is None:
            if len(self._cumulative_rows) >= _CUMULATIVE_MEMO:  # a varying dt must not grow it without end
                self._cumulative_rows.clear()
            rows = _cumulative(self.transitions, condition, float(dt))
            self._cumulative_rows[key] = rows
        return rows

    def kernel_arguments(self, u: MotionInput) -> tuple:
        """Everything `adaptive_move` takes besides poses, state and variates.

        Parameters
        ----------
        u : MotionInput
            The step's motion: command or odometry over `u.dt` [s], and `u.collision`.

        Returns
        -------
        tuple
            (cumulative transitions, vx, vy, ω, dt, collision side or NaN, parameters, redraw each step).
        """
        percept: CollisionPercept = u.collision
        side = percept.side
        vx, vy, omega = self.velocities(u)
        return (
            self.cumulative_transitions(self.condition(percept), u.dt),
            vx,
            vy,
            omega,
            u.dt,
            np.nan if side is None else float(side),
            self.kernel_parameters(u.dt),
            self.redraw == "step",
        )

    def kernel_parameters(self, dt: float) -> np.ndarray:
        """The parameters `adaptive_move` takes for a step of `dt` seconds (read-only (14,)): β1..β7, β_turn, the
        foot separation, eq. 10's `odometry` β times `noise_rate_factor(dt, noise_rate)`, and `stop_creep`. At
        a factor of exactly 1 (dt = 0.01 s, or "per_step") the unscaled memo itself; the others kept per factor.

        Parameters
        ----------
        dt : float
            The time step [s].

        Returns
        -------
        numpy.ndarray
            (14,) float64, read-only.
        """
        factor = noise_rate_factor(dt, self.noise_rate)
        if factor == 1.0:
            return self._kernel_params
        params = self._scaled_params.get(factor)
        if params is None:
            if len(self._scaled_params) >= _CUMULATIVE_MEMO:  # a varying dt must not grow it without end
                self._scaled_params.clear()
            params = self._kernel_params.copy()
            params[9:13] *= factor
            params.flags.writeable = False
            self._scaled_params[factor] = params
        return params

    def predict(
        self, poses: np.ndarray, u: MotionInput, rng: np.random.Generator, state: np.ndarray | None = None
    ) -> None:
        """Move `poses` in place; `state` (N, 4) is each particle's mobility state, updated in place (the
        filter passes its own; None uses a throw-away all-free state, i.e. a single-step prediction).

        Parameters
        ----------
        poses : numpy.ndarray
            (N, 3) float64 poses (x [m], y [m], θ [rad]), moved in place.
        u : MotionInput
            The step's motion: command or odometry over `u.dt` [s], and `u.collision`.
        rng : numpy.random.Generator
            The generator the noise and the transitions are drawn from.
        state : numpy.ndarray or None, default None
            (N, 4) per-particle mobility state (`particle_state`), updated in place.

        Raises
        ------
        ValueError
            If `check` refuses `u`, or the poses or the state have the wrong shape or type.
        """
        check_poses(poses)
        percept = u.collision
        if not isinstance(percept, CollisionPercept) or (u.command is None and u.odometry is None):
            self.check(u)  # raises the ValueError that names what is missing
        self._check_speed(u)
        n = poses.shape[0]
        if state is None:
            state = self.particle_state(n)
        elif state.shape != (n, STATE_COLUMNS) or state.dtype != np.float64:
            raise ValueError(f"state must be float64 of shape ({n}, {STATE_COLUMNS}), got {state.dtype} {state.shape}")
        adaptive_move_drawing(poses, state, *self.kernel_arguments(u), *bit_generator_handle(rng))


@numba.njit(cache=True)
def adaptive_move(poses, state, cumulative, vx, vy, omega, dt, side, params, redraw_each_step, variates):
    """Jump-Markov step of every particle: draw its next mobility state, then move it by its state's velocity
    (Hoffmann eq. 11-26) plus eq. 10's odometry noise on the effective speeds. `variates` (N, 7) uniforms:
    [transition, three episode values (taken when the particle leaves free, or every step with
    `redraw_each_step`), three odometry noise values]; `side` is c(z_c) or NaN.

    Every particle gets, bit for bit, the numbers of the general step at the end of the loop. Free particles
    share their chord, noise bounds and turn, so these are computed once; a stopped particle whose coordinates
    are both non-zero is given a displacement of exactly ±0, which leaves them unchanged."""
    model, odometry = _step_groups(cumulative, vx, vy, omega, dt, side, params, redraw_each_step)
    _adaptive_range(
        poses,
        state,
        model,
        odometry,
        (variates, False, _NO_BASES, _NO_BASES),
        0,
        0,
        poses.shape[0],
        np.empty((MOVE_ROWS, DRAWS)),
    )


@numba.njit(cache=True)
def adaptive_move_drawing(
    poses, state, cumulative, vx, vy, omega, dt, side, params, redraw_each_step, function, generator
):
    """`adaptive_move` with its variates drawn here, a block of particles at a time, from a bit generator
    (`numerics.random.bit_generator_handle`): the same poses and states as `adaptive_move(...,
    rng.random((N, 7)))`, without the (N, 7) array.

    With numpy's PCG64 the three episode values of a particle are computed only when it takes them
    (`draw_rows_deferring`): the generator steps past them all the same, so the numbers are those of the
    (N, 7) array, at four 128-bit multiply-adds per particle instead of seven."""
    n = poses.shape[0]
    variates = np.empty((DRAWS, VARIATES))
    bases = np.empty((DRAWS, 2), dtype=np.uint64)
    increments = np.empty((PCG64_STEPS, 2), dtype=np.uint64)
    rows = np.empty((MOVE_ROWS, DRAWS))
    model, odometry = _step_groups(cumulative, vx, vy, omega, dt, side, params, redraw_each_step)
    for start in range(0, n, DRAWS):
        stop = min(start + DRAWS, n)
        deferred = draw_rows_deferring(function, generator, variates, stop - start, 1, 4, bases, increments)
        _adaptive_range(
            poses, state, model, odometry, (variates, deferred, bases, increments), start, start, stop, rows
        )


MOVE_ROWS = 6  # `_adaptive_range`'s scratch rows: turned heading, dx, dy, new heading, cos, sin
_NO_BASES = np.empty((0, 2), dtype=np.uint64)  # no deferred episode values


# `_adaptive_range` and `_adaptive_block` take their arguments in groups (tuples):
#     model     (cumulative, params, redraw_each_step): the transition table, β and odometry-noise parameters
#     odometry  (vx, vy, omega, dt, side): the step's request and the stopped turn's side c(z_c) (or NaN)
#     draws     (variates, deferred, bases, increments): the particles' uniforms, and whether their episode values
#               are computed from bases and increments (`numerics.random.draw_rows_deferring`)
@numba.njit(cache=True, inline="always")
def _step_groups(cumulative, vx, vy, omega, dt, side, params, redraw_each_step):
    """The groups model and odometry of `_adaptive_range` from `adaptive_move`'s arguments."""
    return (cumulative, params, redraw_each_step), (vx, vy, omega, dt, side)


@numba.njit(cache=True)
def _adaptive_range(poses, state, model, odometry, draws, first, start, stop, rows):
    """`adaptive_move` of particles start..stop-1 (model, odometry, draws: the groups above); particle i's
    variates are all_variates[i - first], whose episode values (columns 1-3) are computed from bases[i - first]
    and increments when `deferred` (`numerics.random.draw_rows_deferring`). rows: (MOVE_ROWS, DRAWS) scratch. A
    block of particles at a time, in two passes: each particle's state and robot-frame displacement, then the
    rotation into the field frame, whose cos and sin take a loop that vectorizes (`sincos`)."""
    all_variates, deferred, bases, increments = draws
    for block in range(start, stop, DRAWS):
        end = min(block + DRAWS, stop)
        _adaptive_block(
            poses,
            state,
            model,
            odometry,
            (all_variates[block - first : end - first], deferred, bases[block - first : end - first], increments),
            block,
            end - block,
            rows,
        )
        _rotate_rows(rows, end - block)
        for p in range(end - block):
            i = block + p
            c = rows[4, p]
            s = rows[5, p]
            dx = rows[1, p]
            dy = rows[2, p]
            poses[i, 0] += c * dx - s * dy
            poses[i, 1] += s * dx + c * dy
            poses[i, 2] = rows[3, p]


@numba.njit(cache=True, error_model="numpy")
def _rotate_rows(rows, count):
    """Rows 4 and 5 (cos and sin) from row 0, row 3 wrapped: a loop that vectorizes."""
    for p in range(count):
        rows[4, p], rows[5, p] = sincos(rows[0, p])
        rows[3, p] = wrap(rows[3, p])


@numba.njit(cache=True)
def _adaptive_block(poses, state, model, odometry, draws, start, count, rows):
    """The states of particles start..start+count-1 (model, odometry, draws: the groups above; variates[p] for
    particle start + p, its episode values from bases[p] when `deferred`), and into rows[:4, p] the heading to
    rotate by, the robot-frame displacement and the new heading (not yet wrapped). A stopped particle whose
    coordinates are both non-zero gets a displacement of exactly zero: ±0 added leaves them unchanged."""
    cumulative, params, redraw_each_step = model
    vx, vy, omega, dt, side = odometry
    variates, deferred, bases, increments = draws
    beta1, beta2, beta3, beta4 = params[0], params[1], params[2], params[3]
    beta5, beta6, beta7, beta_turn, separation = params[4], params[5], params[6], params[7], params[8]
    odo1, odo2, odo3, odo4 = params[9], params[10], params[11], params[12]
    creep = params[13]
    speed = math.sqrt(vx * vx + vy * vy)
    free_half = 0.5 * omega * dt
    free_chord = sincos(free_half)[1] / free_half if abs(free_half) > 1e-9 else 1.0
    free_dx = (vx + 0.0) * dt * free_chord
    free_dy = (vy + 0.0) * dt * free_chord
    free_bound_x = odo1 * speed * dt
    free_bound_y = odo2 * speed * dt
    free_bound_theta = (odo3 * speed + odo4 * abs(omega)) * dt
    free_turn = omega * dt
    side_known = side == side  # not NaN
    stopped_turn_rate = speed / separation * side * beta_turn
    creep_share = creep * abs(side) if side_known else 0.0  # the pivot variant's walk on (0: the paper's)
    for p in range(count):
        i = start + p
        old = int(state[i, 0])
        new = 0
        while variates[p, 0] >= cumulative[old, new]:
            new += 1
        if (old == 0 and new != 0) or redraw_each_step:
            if deferred:
                state[i, 1] = deferred_uniform(bases, increments, p, 1)
                state[i, 2] = deferred_uniform(bases, increments, p, 2)
                state[i, 3] = deferred_uniform(bases, increments, p, 3)
            else:
                state[i, 1] = variates[p, 1]
                state[i, 2] = variates[p, 2]
                state[i, 3] = variates[p, 3]
        if new != old:
            state[i, 0] = new  # (unchanged states stay clean in the cache: no write-back at large N)
        theta = poses[i, 2]
        if new == 0:  # free: the request plus eq. 10's noise
            rows[0, p] = theta + free_half
            rows[1, p] = free_dx + (2.0 * variates[p, 4] - 1.0) * free_bound_x
            rows[2, p] = free_dy + (2.0 * variates[p, 5] - 1.0) * free_bound_y
            rows[3, p] = theta + free_turn + (2.0 * variates[p, 6] - 1.0) * free_bound_theta
            continue
        e1, e2, e3 = state[i, 1], state[i, 2], state[i, 3]
        px, py = 0.0, 0.0  # push velocity
        if new == 4:  # stopped, eq. 23-26
            if side_known:
                w = stopped_turn_rate * e1
            else:
                w = beta7 * (2.0 * e1 - 1.0)
            if creep_share == 0.0 and poses[i, 0] != 0.0 and poses[i, 1] != 0.0:
                # With no walking speed the noise bound of eq. 10 is odo4·|ω'|·dt alone.
                rows[0, p] = theta
                rows[1, p] = 0.0
                rows[2, p] = 0.0
                rows[3, p] = theta + w * dt + (2.0 * variates[p, 6] - 1.0) * (odo4 * abs(w) * dt)
                continue
            # At a zero coordinate the sign of the zero displacement shows.
            ex, ey = (vx * creep_share * e1, vy * creep_share * e1) if creep_share != 0.0 else (0.0, 0.0)
        elif new == 1:  # slippage, eq. 14-15
            factor = beta1 + (1.0 - beta1) * e1
            ex, ey = vx * factor, vy * factor
            w = omega + beta2 * (2.0 * e2 - 1.0)
        elif new == 2:  # hindrance, eq. 16-17
            factor = beta3 + (1.0 - beta3) * e1
            ex, ey = vx * factor, vy * factor
            w = omega * (beta4 + (1.0 - beta4) * e2)
        else:  # pushed, eq. 18-22
            ex, ey = vx, vy
            alpha = math.pi * (2.0 * e1 - 1.0)
            push = beta5 * e2
            c, s = sincos(alpha)
            px, py = push * c, push * s
            w = omega + beta6 * (2.0 * e3 - 1.0)
        walked = math.sqrt(ex * ex + ey * ey)
        bound_x = odo1 * walked * dt
        bound_y = odo2 * walked * dt
        bound_theta = (odo3 * walked + odo4 * abs(w)) * dt
        half = 0.5 * w * dt
        chord = sincos(half)[1] / half if abs(half) > 1e-9 else 1.0
        rows[0, p] = theta + half
        rows[1, p] = (ex + px) * dt * chord + (2.0 * variates[p, 4] - 1.0) * bound_x
        rows[2, p] = (ey + py) * dt * chord + (2.0 * variates[p, 5] - 1.0) * bound_y
        rows[3, p] = theta + w * dt + (2.0 * variates[p, 6] - 1.0) * bound_theta
