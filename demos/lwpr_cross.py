"""The LWPR "cross" benchmark of LWPR.md ("The benchmark users know"), with timings.

    python -m demos.lwpr_cross              # 10 seeds, a table
    python -m demos.lwpr_cross --seeds 3 --json

Per seed: 500 training points uniform on [-1, 1]², targets cross(x) + N(0, 0.1²), 20 epochs each in a
fresh random order; test nMSE on the noiseless 41×41 grid; number of receptive fields; time per update
(the ``LWPR.update`` call, 10 000 calls, input validation and numba dispatch included) and per prediction
(``LWPR.predict`` on one point, over the grid, and per point of one batched ``predict`` call over the grid).
The plain reference implementation (``motion_models.lwpr_reference``) is timed on the first seed and the
numba/reference speed ratio is reported. Reference library (C, one core): nMSE 0.039 ± 0.004, 47.5 ± 1.8 RFs,
1.3–1.7 µs per update, 0.7–0.9 µs per prediction.
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
import time

import numpy as np

from motion_models.lwpr import LWPR
from motion_models.lwpr_reference import ReferenceLWPR

N_TRAIN = 500
N_EPOCHS = 20
GRID = 41
REFERENCE_LIBRARY = {
    "nmse": 0.039,
    "nmse_sd": 0.004,
    "num_rfs": 47.5,
    "num_rfs_sd": 1.8,
    "us_per_update": [1.3, 1.7],
    "us_per_predict": [0.7, 0.9],
}


def cross(x: np.ndarray) -> np.ndarray:
    """f(x₁, x₂) = max(exp(−10x₁²), exp(−50x₂²), 1.25·exp(−5(x₁² + x₂²)))."""
    x1, x2 = x[..., 0], x[..., 1]
    return np.maximum.reduce([np.exp(-10.0 * x1**2), np.exp(-50.0 * x2**2), 1.25 * np.exp(-5.0 * (x1**2 + x2**2))])


def make_model(cls=LWPR):
    """The benchmark settings: init_D = 50·I, init_alpha = 250, w_gen = 0.2, the rest default."""
    model = cls(2, 1)
    model.init_D = 50.0 * np.eye(2)
    model.init_alpha = 250.0 * np.ones((2, 2))
    model.w_gen = 0.2
    return model


def test_grid() -> np.ndarray:
    g = np.linspace(-1.0, 1.0, GRID)
    return np.stack(np.meshgrid(g, g), axis=-1).reshape(-1, 2)


def training_data(seed: int) -> tuple[np.random.Generator, np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    X = rng.uniform(-1.0, 1.0, (N_TRAIN, 2))
    Y = (cross(X) + rng.normal(0.0, 0.1, N_TRAIN))[:, None]
    return rng, X, Y


def train(model, rng: np.random.Generator, X: np.ndarray, Y: np.ndarray) -> float:
    """20 epochs in fresh random orders; returns the seconds spent in update calls."""
    orders = [rng.permutation(N_TRAIN) for _ in range(N_EPOCHS)]
    rows = [(X[i], Y[i]) for order in orders for i in order]
    update = model.update
    start = time.perf_counter()
    for x, y in rows:
        update(x, y)
    return time.perf_counter() - start


def _best_us(fn, calls: int, repeats: int = 5) -> float:
    """Best of ``repeats`` timings of ``calls`` calls, in µs per call (robust to a busy machine)."""
    best = float("inf")
    for _ in range(repeats):
        start = time.perf_counter()
        fn(calls)
        best = min(best, time.perf_counter() - start)
    return best / calls * 1e6


def run_seed(seed: int) -> dict:
    rng, X, Y = training_data(seed)
    model = make_model()
    train_seconds = train(model, rng, X, Y)
    G = test_grid()
    truth = cross(G)
    prediction = model.predict(G)[:, 0]
    nmse = float(np.mean((prediction - truth) ** 2) / np.var(truth))

    # Steady-state update timing: 10 000 more samples on copies of the trained model (the reported model
    # stays the 20-epoch one); best of three.
    samples = [(X[i], Y[i]) for i in np.random.default_rng(seed + 1000).integers(0, N_TRAIN, 10_000)]
    us_update = float("inf")
    for _ in range(3):
        update = model.copy().update
        start = time.perf_counter()
        for x, y in samples:
            update(x, y)
        us_update = min(us_update, (time.perf_counter() - start) / len(samples) * 1e6)
    points = list(G)
    predict = model.predict

    def predictions(count: int) -> None:
        for x in points[:count]:
            predict(x)

    def batch(count: int) -> None:
        model.predict(G)

    us_predict = _best_us(predictions, len(points))
    us_batch = _best_us(batch, 1) / len(G)
    return {
        "seed": seed,
        "nmse": nmse,
        "num_rfs": int(model.num_rfs[0]),
        "us_per_update": us_update,
        "us_per_predict": us_predict,
        "us_per_predict_batched": us_batch,
        "train_seconds": train_seconds,
    }


def reference_timing(seed: int) -> dict:
    """The plain-Python reference on one seed: one epoch of updates and the grid predictions."""
    rng, X, Y = training_data(seed)
    ref = make_model(ReferenceLWPR)
    model = make_model()
    orders = [rng.permutation(N_TRAIN) for _ in range(N_EPOCHS)]
    for order in orders[:-1]:
        for i in order:
            ref.update(X[i], Y[i])
            model.update(X[i], Y[i])
    start = time.perf_counter()
    for i in orders[-1]:
        ref.update(X[i], Y[i])
    us_update_ref = (time.perf_counter() - start) / N_TRAIN * 1e6
    start = time.perf_counter()
    for i in orders[-1]:
        model.update(X[i], Y[i])
    us_update = (time.perf_counter() - start) / N_TRAIN * 1e6
    G = test_grid()
    start = time.perf_counter()
    for x in G:
        ref.predict(x)
    us_predict_ref = (time.perf_counter() - start) / len(G) * 1e6
    start = time.perf_counter()
    for x in G:
        model.predict(x)
    us_predict = (time.perf_counter() - start) / len(G) * 1e6
    return {
        "seed": seed,
        "reference_us_per_update": us_update_ref,
        "reference_us_per_predict": us_predict_ref,
        "speedup_update": us_update_ref / us_update,
        "speedup_predict": us_predict_ref / us_predict,
    }


def _summary(values: list[float]) -> dict:
    return {
        "mean": statistics.fmean(values),
        "median": statistics.median(values),
        "sd": statistics.stdev(values) if len(values) > 1 else 0.0,
    }


PROG = "robocup-mcl bench lwpr"


def build_parser(prog: str = PROG) -> argparse.ArgumentParser:
    """The command's argument parser, named `prog` in its usage line."""
    from mcl.tools.cli_checks import add_progress_option, add_save_option, description

    parser = argparse.ArgumentParser(prog=prog, description=description(__doc__))
    parser.add_argument("--seeds", type=int, default=10, help="number of seeds (default 10)")
    parser.add_argument("--json", action="store_true", help="print one JSON object instead of a table")
    add_save_option(parser)
    add_progress_option(parser)
    return parser


def warm_up_lwpr(progress: bool = False):
    """Compile (or load the cached) LWPR kernels outside the timings: update, predict, and prediction with
    confidence, one group each; returns the `mcl.numba_cache.WarmUp` (a machine's first run says so on stderr)."""
    from mcl.numba_cache import warm_up
    from motion_models import lwpr

    warm = make_model()
    stages = [
        ("update", lambda: warm.update(np.zeros(2), np.zeros(1))),
        ("predict", lambda: (warm.predict(np.zeros(2)), warm.predict(np.zeros((2, 2))))),
        ("predict with confidence", lambda: (warm.predict_conf(np.zeros(2)), warm.predict_conf(np.zeros((2, 2))))),
    ]
    kernels = (lwpr._update_kernel, lwpr._predict_kernel, lwpr._predict_one_kernel)
    return warm_up(stages, kernels, progress=progress)


def main(argv: list[str] | None = None, prog: str = PROG) -> int:
    """`robocup-mcl bench lwpr` (see --help); returns the exit status."""
    from mcl.tools.cli_checks import progress_bar, progress_wanted

    parser = build_parser(prog)
    args = parser.parse_args(argv)
    from mcl.tools.cli_checks import check_output_file, save_json

    check_output_file(args.save, "--save")
    if args.seeds < 1:
        parser.error(f"--seeds must be at least 1, got {args.seeds}")
    progress = progress_wanted(args)
    warm = warm_up_lwpr(progress)  # outside the timings

    runs = [run_seed(seed) for seed in progress_bar(range(args.seeds), enabled=progress, desc="lwpr", unit="seed")]
    reference = reference_timing(0)
    keys = ("nmse", "num_rfs", "us_per_update", "us_per_predict", "us_per_predict_batched")
    summary = {key: _summary([float(run[key]) for run in runs]) for key in keys}
    result = {
        "benchmark": "lwpr cross",
        "n_train": N_TRAIN,
        "epochs": N_EPOCHS,
        "grid": f"{GRID}x{GRID}",
        "seeds": runs,
        "summary": summary,
        "reference_python": reference,
        "reference_library": REFERENCE_LIBRARY,
        **warm.as_dict(),
    }
    save_json(args.save, result)
    if args.json:
        print(json.dumps(result, indent=2))
        return 0

    print(f"LWPR cross benchmark: {N_TRAIN} points, {N_EPOCHS} epochs, {GRID}x{GRID} test grid")
    print(f"{'seed':>4}  {'nMSE':>7}  {'#RFs':>4}  {'us/update':>9}  {'us/predict':>10}  {'us/pt batched':>13}")
    for run in runs:
        print(
            f"{run['seed']:>4}  {run['nmse']:7.4f}  {run['num_rfs']:>4}  {run['us_per_update']:9.2f}  "
            f"{run['us_per_predict']:10.2f}  {run['us_per_predict_batched']:13.2f}"
        )
    for stat in ("mean", "median"):
        s = {key: summary[key][stat] for key in keys}
        print(
            f"{stat:>6}  {s['nmse']:5.4f}  {s['num_rfs']:4.1f}  {s['us_per_update']:9.2f}  "
            f"{s['us_per_predict']:10.2f}  {s['us_per_predict_batched']:13.2f}"
        )
    lib = REFERENCE_LIBRARY
    print(
        f"reference library (C): nMSE {lib['nmse']} ± {lib['nmse_sd']}, {lib['num_rfs']} ± {lib['num_rfs_sd']} "
        f"RFs, {lib['us_per_update'][0]}–{lib['us_per_update'][1]} us/update, "
        f"{lib['us_per_predict'][0]}–{lib['us_per_predict'][1]} us/predict"
    )
    print(
        f"plain-Python reference (seed 0): {reference['reference_us_per_update']:.1f} us/update, "
        f"{reference['reference_us_per_predict']:.1f} us/predict; numba is "
        f"{reference['speedup_update']:.0f}x / {reference['speedup_predict']:.0f}x faster"
    )
    print(f"warm-up: {warm.summary()}, not counted in the timings")
    return 0


if __name__ == "__main__":
    sys.exit(main())
