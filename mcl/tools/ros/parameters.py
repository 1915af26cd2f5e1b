"""The node's parameters: one frozen `NodeSettings`, its ROS parameter names, defaults and checks.

    from mcl.tools.ros.parameters import NodeSettings

    settings = NodeSettings(field="kidsize", particles=300)        # ValueError naming a bad field and value
    settings.localizer()                                           # the Localizer these settings build

Every field is a ROS parameter of the same name (`ros2 run ... --ros-args -p particles:=300`, or
`robocup-mcl node --particles 300`); the command line's option sets the default the ROS parameter overrides.
Topics and frames follow `mcl.tools.logs.mcap_io.Topics` and `robocup-mcl replay` (the Humanoid League's names), so
a log recorded on the robot replays with the same topics the node listens to. A topic set to "" is not
subscribed (or published).
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, fields
from typing import Any

from mcl.tools.logs.mcap_io import Topics

_TOPICS = Topics()
EVENTS = (
    "initial_placement",
    "kickoff_placement",
    "kickoff_placement_defending",
    "manual_placement",
    "anywhere_in_own_half",
    "penalized",
    "penalty_return",
    "fallen",
    "got_up",
)
STARTS = ("own_half", "field", "initial", "penalty")


@dataclass(frozen=True)
class NodeSettings:
    """What the node runs with (each field is a ROS parameter of the same name).

    Attributes
    ----------
    field : str
        spl, kidsize, adultsize, or a field file (.toml/.json).
    model : str
        The motion model: "velocity-linear" or "constant" (`mcl.tools.replay.MODELS`); not used with `profile`.
    particles : int
        Number of particles (> 0).
    seed : int
        Seed of the filter's random generator.
    history : float
        Seconds of motion kept for late camera frames (> 0).
    compensate_latency : bool
        Score each camera frame at its capture time (its header stamp).
    profile : str
        A localizer profile (`mcl.profile`, what `robocup-mcl tune` writes); "" for none. `particles`, `seed`,
        `history` and `compensate_latency` given here win over it.
    start : str
        The belief at start: own_half, field, initial (the touchlines) or penalty (`robocup-mcl replay --start`).
    player_number : int
        The robot's own number (1..20); 0: not known.
    map_frame, odom_frame : str
        The TF frames of the field and of the odometry.
    publish_tf : bool
        Publish map -> odom on /tf after each odometry message.
    odometry_topic, commands_topic, goalposts_topic, markings_topic, balls_topic, game_state_topic : str
        Inputs: nav_msgs/Odometry, geometry_msgs/Twist, soccer_vision_3d_msgs GoalpostArray, MarkingArray and
        BallArray, game_controller_hl_interfaces/GameState.
    event_topic, initial_pose_topic : str
        Inputs: std_msgs/String game events (`EVENTS`), geometry_msgs/PoseWithCovarianceStamped (a known pose).
    team_topic : str
        Input: robocup_mcl_msgs/TeamMessage, the teammates' broadcasts (`Localizer.team_message`).
    pose_topic, quality_topic, lost_topic, hypotheses_topic : str
        Outputs: PoseWithCovarianceStamped per odometry message; std_msgs/String quality and std_msgs/Bool
        lost when they change (latched); geometry_msgs/PoseArray of the hypotheses, most probable first.
    hypotheses_rate : float
        How often the hypotheses are published [Hz]; 0: never.
    particles_topic : str
        Output: geometry_msgs/PoseArray of the filter's particles (in `map_frame`), `particles_rate` times a second.
    particles_rate : float
        How often the particles are published [Hz]; 0: never.
    field_topic : str
        Output: visualization_msgs/MarkerArray of the field (lines, centre circle, goalposts, penalty and centre
        marks, in `map_frame`), published once at start, latched (transient local).
    use_source_timestamps : bool
        Order a camera frame against the odometry by the messages' DDS source timestamps, where rclpy passes them
        (`MessageInfo`, from Iron on); False, or on Humble: by the order the messages are taken and their header
        stamps (`mcl.tools.ros.core`).
    game_events : bool
        Follow the GameState: INITIAL places the robot on the touchlines, a penalty and its end are
        `penalized` and `penalty_return`.
    """

    field: str = "spl"
    model: str = "velocity-linear"
    particles: int = 500
    seed: int = 0
    history: float = 1.0
    compensate_latency: bool = True
    profile: str = ""
    start: str = "own_half"
    player_number: int = 0
    map_frame: str = "map"
    odom_frame: str = "odom"
    publish_tf: bool = True
    odometry_topic: str = _TOPICS.odometry
    commands_topic: str = _TOPICS.commands
    goalposts_topic: str = _TOPICS.goalposts
    markings_topic: str = _TOPICS.markings
    balls_topic: str = "/balls_relative"
    game_state_topic: str = "/gamestate"
    event_topic: str = "/robocup_mcl/event"
    initial_pose_topic: str = "/initialpose"
    team_topic: str = "/robocup_mcl/team"
    pose_topic: str = _TOPICS.pose_out
    quality_topic: str = "/robocup_mcl/quality"
    lost_topic: str = "/robocup_mcl/lost"
    hypotheses_topic: str = "/robocup_mcl/hypotheses"
    hypotheses_rate: float = 2.0
    particles_topic: str = "/robocup_mcl/particles"
    particles_rate: float = 2.0
    field_topic: str = "/robocup_mcl/field"
    use_source_timestamps: bool = True
    game_events: bool = True

    def __post_init__(self) -> None:
        from mcl.tools.replay import MODELS

        for f in fields(self):
            value: Any = getattr(self, f.name)
            kind = {"int": int, "float": float, "bool": bool, "str": str}[str(f.type)]
            if kind is float and isinstance(value, int) and not isinstance(value, bool):
                object.__setattr__(self, f.name, float(value))
                value = float(value)
            if not isinstance(value, kind) or (kind is int and isinstance(value, bool)):
                raise ValueError(f"{f.name} = {value!r} must be a {kind.__name__}")
            if f.name.endswith("_topic") and value and (str(value) != str(value).strip() or " " in str(value)):
                raise ValueError(f"{f.name} = {value!r} must be a topic name (or '' for none)")
        if self.model not in MODELS:
            raise ValueError(f"model = {self.model!r} must be one of {tuple(MODELS)}")
        if self.particles <= 0:
            raise ValueError(f"particles = {self.particles} must be > 0")
        if not (math.isfinite(self.history) and self.history > 0):
            raise ValueError(f"history = {self.history} must be a positive number of seconds")
        if self.start not in STARTS:
            raise ValueError(f"start = {self.start!r} must be one of {STARTS}")
        if not 0 <= self.player_number <= 20:
            raise ValueError(f"player_number = {self.player_number} must be 1..20, or 0 for not known")
        for rate in ("hypotheses_rate", "particles_rate"):
            value = getattr(self, rate)
            if not (math.isfinite(value) and value >= 0):
                raise ValueError(f"{rate} = {value} must be >= 0 Hz")
        if not self.map_frame or not self.odom_frame:
            raise ValueError("map_frame and odom_frame must not be empty")

    @classmethod
    def from_dict(cls, values: dict[str, Any]) -> NodeSettings:
        """Settings from a dict of parameter values (unknown names are a ValueError)."""
        known = {f.name for f in fields(cls)}
        unknown = sorted(set(values) - known)
        if unknown:
            raise ValueError(f"unknown parameters {unknown}; the node's parameters: {', '.join(sorted(known))}")
        return cls(**values)

    def as_dict(self) -> dict[str, Any]:
        """The parameters by name."""
        return asdict(self)

    def localizer(self):
        """The `mcl.localizer.Localizer` these settings build (its field, model or profile, particles, seed,
        history, latency compensation and player number), its belief not yet started (`NodeCore` starts it)."""
        from field.io import field_by_name_or_path
        from mcl.localizer import Localizer
        from mcl.side import Team
        from mcl.tools.replay import MODELS

        field = field_by_name_or_path(self.field)
        player = self.player_number or None
        if self.profile:
            from mcl.profile import Profile

            return Profile.load(self.profile).localizer(
                field,
                seed=self.seed,
                n_particles=self.particles,
                history=self.history,
                compensate_latency=self.compensate_latency,
                team=Team(player),
            )
        return Localizer(
            field,
            MODELS[self.model](),
            n_particles=self.particles,
            seed=self.seed,
            history=self.history,
            compensate_latency=self.compensate_latency,
            team=Team(player),
        )
