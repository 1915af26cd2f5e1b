"""The project's numeric kernels, shared by every package that needs them (the bottom layer, with `field`).

- `numerics.random`: the filter's one numpy Generator drawn from compiled code (PCG64 stepped in kernels,
  threads drawing chunks of one stream), the same numbers as `rng.random()` and `rng.integers()`.
- `numerics.trig`: angle wrapping and the polynomial sin, cos and atan2 that vectorize and give the same bits
  on every machine, with their numpy twins; `FAST`, the flags of the opt-in fast-math kernels.
- `numerics.chunks`: chunk sizes for spreading particles over threads.
"""
