"""Monte Carlo localization: the particle filter core, and the robot-facing layer on top of it.

    from mcl import ParticleFilter

See `mcl.filter` for a complete example. The core (`mcl.filter`; its particles `mcl.particles` and summary
`mcl.summary`; the engine that runs its stages `mcl.engine`, with its fused compiled step `mcl.step`; and its
kernels `mcl.weights`, `mcl.resampling`, `mcl.estimate`, `mcl.latency`) knows motion and sensor models only by
their contracts (`mcl.contracts`); the soccer rules are `mcl.relocalization`. On top: `mcl.localizer` (a robot's
loop), `mcl.logs` and `mcl.replay`, `mcl.recording` (Rerun), `mcl.cli`. `mcl.testing` holds hypothesis
strategies and invariant checks for a team's own tests. The layers: docs/architecture.md.
"""
from .filter import AugmentedMCL, ParticleFilter
from .summary import Entropy, Estimate, Grid

__all__ = ["ParticleFilter", "AugmentedMCL", "Estimate", "Entropy", "Grid"]
