"""Monte Carlo localization core: the particle filter, resampling, estimate, entropy, recording.

    from mcl import ParticleFilter

See `mcl.filter` for a complete example. The core knows motion and sensor models only by their interfaces.
"""
from .filter import AugmentedMCL, Entropy, Estimate, Grid, ParticleFilter

__all__ = ["ParticleFilter", "AugmentedMCL", "Estimate", "Entropy", "Grid"]
