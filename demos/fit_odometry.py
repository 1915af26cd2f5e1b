"""`robocup-mcl fit odometry`: LWPR's meta-parameters for the learned footstep odometry, and the linear
baseline's setting, from training logs only.

    robocup-mcl fit odometry [--json] [--save results/odometry_fit.json]

    from demos.fit_odometry import fit, score_lwpr, score_baseline

Training logs: on each surface, one 300 s log of each training robot (`demos.odometry.TRAIN_ROBOTS`, drawn
from `demos.footstep_sim.ROBOT_RANGES` at spread 1, each log under its own drawn `Conditions`; seeds
`demos.odometry.fleet_seed("train", ...)`). As the paper tunes its meta-parameters (Rouxel sec. IV-B 2), each
robot's models learn on the first half of its log and are scored on the second half: the score of a setting
is the mean, over surfaces and input sets (a priori, online), of the learned odometry's mean drift after
10 s divided by the raw odometry's, over the second halves' 20 s sequences (lower is better; 1 is no gain).
No held-out robot or seed is used.

Search (coordinate search on a fixed grid, in two stages): `init_D` × `init_alpha` (`STAGE_1`) with `w_gen`
and `penalty` at the first value of `STAGE_2`'s lists; then `w_gen` × `penalty` at the best pair. The other
fields of `LWPRSettings` (forgetting, epochs, input floor, target) are not searched and are written as
"fixed". The linear baseline (`demos.odometry.LinearCorrection`) gets the same treatment: each of its
settings (`BASELINE_GRID`: the inputs it uses and the ridge penalty) is scored by the same rule, per input set.
`motion_models.learned_odometry.LWPRSettings`' defaults and `demos.odometry.BASELINE` are the values this
command wrote to results/odometry_fit.json (a test checks them against the file).
"""

from __future__ import annotations

import argparse
import dataclasses
import time

import numpy as np

from demos.footstep_sim import truth_displacements
from demos.odometry import KINDS, TRAIN_ROBOTS, LinearCorrection, fleet_log, halves, sequence_errors, step_inputs
from motion_models.learned_odometry import LearnedFootstepOdometry, LWPRSettings

SURFACE_NAMES = ("carpet", "grass")
# Half-decade grids (10^(k/2)): the first value of each STAGE_2 list is where stage 1 holds it.
STAGE_1 = {
    "init_D": tuple(10 ** (k / 2) for k in range(-6, 2)),
    "init_alpha": tuple(10 ** (k / 2) for k in range(-1, 4)),
}
STAGE_2 = {"w_gen": tuple(10 ** (k / 4) for k in (-4, -5, -3)), "penalty": tuple(10**k for k in (-6, -4, -2))}
BASELINE_GRID = tuple({"features": f, "ridge": r} for f in ("axis", "inputs") for r in (0.0, 1e-3, 1e-2, 1e-1))
FITTED = ("init_D", "init_alpha", "w_gen", "penalty")
TRAINING_SPREAD = 1.0
PROG = "robocup-mcl fit odometry"


def training_logs(
    surfaces=SURFACE_NAMES, robots=TRAIN_ROBOTS, spread: float = TRAINING_SPREAD, duration: float = 300.0
) -> list:
    """(surface, learning half, tuning half) of log 0 of each training robot on each surface."""
    out = []
    for surface in surfaces:
        for robot in robots:
            first, second = halves(fleet_log("train", surface, robot, 0, spread, duration))
            out.append((surface, first, second))
    return out


def _score(logs: list, make_models) -> dict:
    """Per input set, mean learned / mean raw drift after 10 s on the tuning halves, pooled per surface then
    averaged over surfaces; `make_models(first_half, kind)` returns {"model": ...}."""
    per = {kind: {} for kind in KINDS}
    for surface, first, second in logs:
        for kind in KINDS:
            errors = sequence_errors(second, kind, make_models(first, kind))
            raw, model = per[kind].setdefault(surface, ([], []))
            raw.extend(errors["raw"])
            model.extend(errors["model"])
    return {kind: float(np.mean([np.mean(m) / np.mean(r) for r, m in per[kind].values()])) for kind in KINDS}


def score_lwpr(logs: list, settings: LWPRSettings, seed: int = 0) -> dict:
    """The LWPR score per input set (see the module docstring) and their mean under "mean"."""

    def make(first, kind):
        return {
            "model": LearnedFootstepOdometry.train(
                step_inputs(first, kind), truth_displacements(first), kind, seed=seed, settings=settings
            )
        }

    per_kind = _score(logs, make)
    return {**per_kind, "mean": float(np.mean(list(per_kind.values())))}


def score_baseline(logs: list, setting: dict) -> dict:
    """The linear baseline's score per input set for one setting (features, ridge)."""

    def make(first, kind):
        return {"model": LinearCorrection.fit(step_inputs(first, kind), truth_displacements(first), kind, **setting)}

    return _score(logs, make)


def fit(
    surfaces=SURFACE_NAMES, robots=TRAIN_ROBOTS, seed: int = 0, progress: bool = False, duration: float = 300.0
) -> dict:
    """The search of the module docstring; returns the fitted settings, the fixed ones, every candidate's score
    and the baseline's choice per input set."""
    from mcl.tools.cli_checks import progress_bar

    logs = training_logs(surfaces, robots, duration=duration)
    base = LWPRSettings()
    candidates = []
    stage_1 = [dict(zip(STAGE_1, v)) for v in np.array(np.meshgrid(*STAGE_1.values(), indexing="ij")).reshape(2, -1).T]
    start = {name: values[0] for name, values in STAGE_2.items()}
    for values in progress_bar(stage_1, enabled=progress, desc="fit stage 1", unit="setting"):
        point = {**{k: float(v) for k, v in values.items()}, **start}
        candidates.append({"stage": 1, **point, "score": score_lwpr(logs, dataclasses.replace(base, **point), seed)})
    best_1 = min((c for c in candidates if c["stage"] == 1), key=lambda c: c["score"]["mean"])
    stage_2 = [{"w_gen": w, "penalty": p} for w in STAGE_2["w_gen"] for p in STAGE_2["penalty"]]
    for values in progress_bar(stage_2, enabled=progress, desc="fit stage 2", unit="setting"):
        point = {"init_D": best_1["init_D"], "init_alpha": best_1["init_alpha"], **values}
        if values == start:
            score = best_1["score"]
        else:
            score = score_lwpr(logs, dataclasses.replace(base, **point), seed)
        candidates.append({"stage": 2, **point, "score": score})
    best = min(candidates, key=lambda c: (c["score"]["mean"], c["stage"]))
    baseline_scores = [{**setting, "score": score_baseline(logs, setting)} for setting in BASELINE_GRID]
    baseline = {kind: min(baseline_scores, key=lambda c: c["score"][kind]) for kind in KINDS}
    fixed = {k: v for k, v in dataclasses.asdict(base).items() if k not in FITTED}
    return {
        "protocol": {
            "surfaces": list(surfaces),
            "train_robots": list(robots),
            "spread": TRAINING_SPREAD,
            "log_seconds": duration,
            "seed": seed,
            "logs": len(logs),
            "score": "mean over surfaces of mean learned / mean raw drift after 10 s on the second "
            "halves, per input set; LWPR: mean over input sets",
        },
        "settings": {k: best[k] for k in FITTED},
        "score": best["score"],
        "fixed": fixed,
        "baseline": {
            kind: {"features": b["features"], "ridge": b["ridge"], "score": b["score"][kind]}
            for kind, b in baseline.items()
        },
        "candidates": candidates,
        "baseline_candidates": baseline_scores,
    }


def _print(result: dict) -> None:
    p = result["protocol"]
    print(
        f"LWPR meta-parameters fitted on {p['logs']} training logs ({', '.join(p['surfaces'])}; robots "
        f"{p['train_robots'][0]}-{p['train_robots'][-1]}, spread {p['spread']:g}): learn on the first half, "
        "score on the second"
    )
    print("score = learned / raw drift after 10 s (lower is better)")
    print(
        f"{'stage':>5} {'init_D':>7} {'init_alpha':>10} {'w_gen':>6} {'penalty':>8} {'apriori':>8} {'online':>7} "
        f"{'mean':>6}"
    )
    for c in result["candidates"]:
        s = c["score"]
        print(
            f"{c['stage']:>5} {c['init_D']:>7g} {c['init_alpha']:>10g} {c['w_gen']:>6g} {c['penalty']:>8g} "
            f"{s['apriori']:>8.3f} {s['online']:>7.3f} {s['mean']:>6.3f}"
        )
    s = result["settings"]
    print(
        f"fitted: init_D = {s['init_D']:g}, init_alpha = {s['init_alpha']:g}, w_gen = {s['w_gen']:g}, "
        f"penalty = {s['penalty']:g} (score {result['score']['mean']:.3f}); fixed: "
        + ", ".join(f"{k} = {v}" for k, v in result["fixed"].items())
    )
    print("\nlinear baseline (score = baseline / raw drift after 10 s):")
    for c in result["baseline_candidates"]:
        print(
            f"  features {c['features']:<6} ridge {c['ridge']:<6g} apriori {c['score']['apriori']:.3f} "
            f"online {c['score']['online']:.3f}"
        )
    print(
        "chosen: "
        + ", ".join(
            f"{k}: features {b['features']}, ridge {b['ridge']:g} (score {b['score']:.3f})"
            for k, b in result["baseline"].items()
        )
    )


def build_parser(prog: str = PROG) -> argparse.ArgumentParser:
    """The command's argument parser, named `prog` in its usage line.

    Parameters
    ----------
    prog : str, optional
        The program name shown in the usage line.

    Returns
    -------
    argparse.ArgumentParser
        The parser.
    """
    from mcl.tools.cli_checks import add_progress_option, add_save_option, description

    parser = argparse.ArgumentParser(prog=prog, description=description(__doc__))
    parser.add_argument("--seed", type=int, default=0, help="seed of the LWPR training passes (default 0)")
    parser.add_argument("--json", action="store_true", help="print JSON instead of tables")
    add_save_option(parser)
    add_progress_option(parser)
    return parser


def main(argv: list[str] | None = None, prog: str = PROG) -> int:
    """`robocup-mcl fit odometry` (see --help); returns the exit status.

    Parameters
    ----------
    argv : list of str, optional
        The arguments (default: the command line).
    prog : str, optional
        The program name for the usage line.

    Returns
    -------
    int
        The exit status (0).
    """
    from mcl.tools.cli_checks import check_output_file, progress_wanted, save_and_print

    parser = build_parser(prog)
    args = parser.parse_args(argv)
    check_output_file(args.save, "--save")
    started = time.perf_counter()
    result = fit(seed=args.seed, progress=progress_wanted(args))
    save_and_print(result, args.save, args.json, _print)
    if not args.json:
        print(f"\n({time.perf_counter() - started:.0f} s)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
