"""The benchmark and measurement harness: run from a clone, not installed (`robocup-mcl bench`, `soak`).

The library never imports it; it imports the library, the simulators in `demos`, and the numpy twins it times
the kernels against (`benchmarks.reference`). `python -m benchmarks.structure` measures the code's structure.
"""
