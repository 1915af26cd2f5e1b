"""The tuning report: the text table, and the convergence and parameter-importance plots (PNG, matplotlib)."""

from __future__ import annotations

import math
import os
from typing import Any

FIGURES = (
    ("fail_share", "fail share", "{:.1%}"),
    ("rmse_position_m", "RMSE position [m]", "{:.3f}"),
    ("superb_wrong", "SUPERB wrong", "{:.2%}"),
    ("never", "never re-converged", "{:d}"),
    ("truth_loss", "truth loss", "{:.4f}"),
    ("evidence_per_frame", "evidence / frame", "{:.3f}"),
)


def spearman(x, y) -> float | None:
    """Spearman's rank correlation of two equal-length sequences (None for fewer than 3 pairs or no spread)."""
    from scipy.stats import spearmanr

    pairs = [(a, b) for a, b in zip(x, y) if a is not None and b is not None and math.isfinite(a) and math.isfinite(b)]
    if len(pairs) < 3:
        return None
    value = spearmanr([a for a, _ in pairs], [b for _, b in pairs]).statistic
    return None if value != value else float(value)


def _cell(value: Any, fmt: str) -> str:
    if value is None:
        return "–"
    return fmt.format(int(value)) if fmt == "{:d}" else fmt.format(value)


def format_report(result: dict) -> str:
    """The printed report of `robocup-mcl tune` (its JSON result)."""
    s = result["settings"]
    lines = [
        f"tune: {s['trials']} trials ({s['sampler']}, seed {s['seed']}), objective {s['objective']}, "
        f"{s['training_cases']} training cases × {len(s['seeds'])} filter seed(s), "
        f"{s['holdout_cases']} held-out cases" + (f", study {s['study']}" if s.get("study") else "")
    ]
    r = result["ray"]
    first, later = r.get("first_task_s"), r.get("later_task_s")
    lines.append(
        f"Ray: {r['address']}, {r['cpus']} CPUs on {r['nodes']} node(s); {r['tasks']} tasks on "
        f"{r['workers_seen']} worker(s); a worker's first task {_cell(first, '{:.2f}')} s, later tasks "
        f"{_cell(later, '{:.2f}')} s (median); {result['trials_per_hour']:.0f} trials per hour"
    )
    if result["resumed"]:
        lines.append(f"resumed a study with {result['resumed']} completed trials")
    best = result["best"]
    start = next((t for t in result["trials"] if t.get("start")), None)
    lines.append(
        f"best trial {best['trial']}: {best['value']:.4f}"
        + (f" (the defaults, trial {start['number']}: {start['value']:.4f})" if start else "")
    )
    defaults = result["defaults"]
    for name, value in best["values"].items():
        default = defaults.get(name)
        lines.append(f"  {name} = {value!r}" + (f"   (default {default!r})" if default is not None else ""))
    if result["importance"]:
        lines.append("importance: " + ", ".join(f"{k} {v:.2f}" for k, v in result["importance"].items()))
    if result.get("evidence_vs_error"):
        e = result["evidence_vs_error"]
        lines.append(
            f"evidence against error over {e['trials']} trials: Spearman {_cell(e['spearman'], '{:+.2f}')} "
            "between the mean log evidence per frame and the truth loss (negative: more evidence, less "
            "error)"
        )
    lines.append("")
    header = f"{'':<22}" + "".join(f"{name:>24}" for name in ("training", "held-out"))
    lines.append(header)
    lines.append(f"{'':<22}" + "".join(f"{'default':>12}{'tuned':>12}" for _ in range(2)))
    for key, label, fmt in FIGURES:
        row = f"{label:<22}"
        for split in ("training", "holdout"):
            part = result["comparison"].get(split)
            for which in ("default", "tuned"):
                row += f"{_cell(part[which].get(key) if part else None, fmt):>12}"
        lines.append(row)
    per_case = result["comparison"].get("holdout", {}).get("per_case") or []
    if per_case:
        lines += ["", "held-out, per case: fail share / RMSE [m] / evidence per frame, default | tuned"]
        for row in per_case:
            cells = []
            for which in ("default", "tuned"):
                f = row[which]
                cells.append(
                    f"{_cell(f.get('fail_share'), '{:.1%}')} / {_cell(f.get('rmse_position_m'), '{:.3f}')} / "
                    f"{_cell(f.get('evidence_per_frame'), '{:.2f}')}"
                )
            lines.append(f"  {row['case']:<26} {cells[0]:>28} | {cells[1]}")
    return "\n".join(lines)


def plot(result: dict, directory: str) -> list[str]:
    """convergence.png (each trial's value and the best so far) and importance.png (PED-ANOVA importance of each
    parameter) in `directory`; returns the paths written."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    os.makedirs(directory, exist_ok=True)
    written = []
    trials = result["trials"]
    numbers = [t["number"] for t in trials]
    values = [t["value"] for t in trials]
    best, so_far = math.inf, []
    for v in values:
        best = min(best, v)
        so_far.append(best)
    fig, ax = plt.subplots(figsize=(7, 4))
    ax.plot(numbers, values, "o", ms=4, alpha=0.6, label="trial")
    ax.step(numbers, so_far, where="post", color="C3", label="best so far")
    ax.set_xlabel("trial")
    ax.set_ylabel(f"objective ({result['settings']['objective']}, lower is better)")
    ax.set_title("tuning convergence")
    ax.legend()
    fig.tight_layout()
    path = os.path.join(directory, "convergence.png")
    fig.savefig(path, dpi=110)
    plt.close(fig)
    written.append(path)
    importance = result["importance"]
    if importance:
        fig, ax = plt.subplots(figsize=(7, 0.5 + 0.4 * len(importance)))
        names = list(importance)[::-1]
        ax.barh(names, [importance[n] for n in names], color="C0")
        ax.set_xlabel("importance (PED-ANOVA, share of the top trials' spread)")
        ax.set_title("parameter importance")
        fig.tight_layout()
        path = os.path.join(directory, "importance.png")
        fig.savefig(path, dpi=110)
        plt.close(fig)
        written.append(path)
    return written
