"""Monte Carlo localization: the particle filter core, and the robot-facing layer on top of it.

    from mcl import ParticleFilter

See `mcl.filter` for a complete example. The core (`mcl.filter`; its particles `mcl.particles` and summary
`mcl.summary`; the engine that runs its stages `mcl.engine`, with its fused compiled step `mcl.step`; and its
kernels `mcl.weights`, `mcl.resampling`, `mcl.estimate`, `mcl.latency`) knows motion and sensor models only by
their contracts (`mcl.contracts`); the soccer rules are `mcl.relocalization` and `mcl.side`, and a robot's loop
is `mcl.localizer`. The tools around it (logs, replay, Rerun recording, the ROS 2 node, the command line,
tuning, evaluation, the testing kit) are `mcl.tools`, which the core never imports. The layers:
docs/architecture.md.
"""

from field.moved import keep_old_names

from .filter import AugmentedMCL, ParticleFilter
from .summary import Entropy, Estimate, Grid

__all__ = ["ParticleFilter", "AugmentedMCL", "Estimate", "Entropy", "Grid"]

# The tools moved to mcl.tools; their old names still import, with a DeprecationWarning.
keep_old_names(
    {
        f"mcl.{name}": f"mcl.tools.{name}"
        for name in (
            "logs",
            "formats",
            "replay",
            "recording",
            "evaluation",
            "cli",
            "cli_checks",
            "tuning",
            "ros",
            "testing",
        )
    }
)
