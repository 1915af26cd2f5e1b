"""Build hooks of the documentation site (mkdocs.yml `hooks:`).

The home page is the README: `index.md` holds one line, and this hook puts the README in its place with its
links made relative to the docs folder, so the two never differ.

Tables from results files: a line `<!-- results-table: NAME -->` in a page is replaced by the table `NAME`
built from the JSON files the commands wrote (`TABLES`), so a new measurement changes the page when the site is
built. A missing file or key fails the build.

The API reference is one page per module, generated here from the packages' source files (`API_PACKAGES`):
`api/<package>.md` lists a package's modules, `api/<package>/<module>.md` documents one, and the navigation's
"API reference" section lists them all. A new module gets its page without an edit here.

Offline: the TeX of the pages (`$...$`, `$$...$$`, through pymdownx.arithmatex) is turned into MathML when
the site is built (latex2mathml), which browsers render without a script; the theme loads no web fonts
(`theme.font: false`). The docstrings' code blocks are highlighted as Python.

The build does not depend on the current directory: the snippets' base path is set to the repository root.
"""

from __future__ import annotations

import ast
import html
import json
import re
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def readme_as_home() -> str:
    """The README with links into docs/ made relative to docs/, and links to other repository files made
    public text (the site holds only docs/)."""
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    text = re.sub(r"\]\(docs/", "](", text)
    return re.sub(r"\[([^\]]+)\]\((LICENSE)\)", r"`\2`", text)


def _load(name: str) -> dict:
    return json.loads((ROOT / "results" / name).read_text(encoding="utf-8"))


def _seconds(summary: dict) -> str:
    """Median / worst re-convergence with the count that never re-converged ("–" when nothing to re-converge
    from)."""
    if not summary["runs"] and not summary["never"]:
        return "–"
    median = "never" if summary["median"] is None else f"{summary['median']:.2f}"
    worst = "never" if summary["worst"] is None else f"{summary['worst']:.2f}"
    never = f", {summary['never']} never" if summary["never"] else ""
    return f"{median} / {worst}{never}"


def battery_families() -> str:
    """The evaluation battery's held-out runs per family, detections only and with the camera's view
    (results/eval_holdout.json, results/eval_holdout_view.json)."""
    plain = _load("eval_holdout.json")["splits"]["holdout"]["families"]
    view = _load("eval_holdout_view.json")["splits"]["holdout"]["families"]
    rows = [
        "| family | re-converge [s], detections only | with view | fail share, detections only | with view "
        "| on the mirror | RMSE m / °, detections only |",
        "|---|---|---|---|---|---|---|",
    ]
    for family, entry in plain.items():
        a, b = entry["summary"], view[family]["summary"]
        rows.append(
            f"| {family} | {_seconds(a['reconverge_s'])} | {_seconds(b['reconverge_s'])} | "
            f"{100 * a['fail_share']['median']:.1f} / {100 * a['fail_share']['worst']:.0f} % | "
            f"{100 * b['fail_share']['median']:.1f} / {100 * b['fail_share']['worst']:.0f} % | "
            f"{a['on_mirror']} / {b['on_mirror']} | "
            f"{a['rmse_position_m']['median']:.3f} / {a['rmse_heading_deg']['median']:.1f} |"
        )
    return "\n".join(rows)


def battery_quality() -> str:
    """The quality signal pooled over every held-out step, detections only and with the view."""
    plain = _load("eval_holdout.json")["splits"]["holdout"]["overall"]["pooled"]
    view = _load("eval_holdout_view.json")["splits"]["holdout"]["overall"]["pooled"]
    lines = [
        ("SUPERB steps more than 0.5 m off", "SUPERB", 2),
        ("OKAY steps more than 0.5 m off", "OKAY", 1),
        ("SUPERB coverage of the steps within 0.3 m", "superb_coverage", 1),
        ("`is_lost` recall", "recall", 1),
        ("`is_lost` false alarms", "false_alarm", 2),
    ]
    rows = ["| | detections only | with view |", "|---|---|---|"]
    rows += [
        f"| {label} | {100 * plain[key]['share']:.{digits}f} % | {100 * view[key]['share']:.{digits}f} % |"
        for label, key, digits in lines
    ]
    return "\n".join(rows)


def battery_targets() -> str:
    """The held-out battery against the evaluation's targets (results/eval_holdout.json, and the view run's
    pooled quality in brackets)."""
    split = _load("eval_holdout.json")["splits"]["holdout"]
    families = {name: entry["summary"] for name, entry in split["families"].items()}
    pooled = split["overall"]["pooled"]
    view = _load("eval_holdout_view.json")["splits"]["holdout"]["overall"]["pooled"]
    runs = split["overall"]["runs"]

    on_mirror = {name: f["on_mirror"] for name, f in families.items() if f["on_mirror"]}
    odds = [f["kidnap_odds"] for f in families.values() if f.get("kidnap_odds")]
    clear = [sum(o["clear"][k] for o in odds) for k in ("on_mirror", "runs")]
    even = [sum(o["even"][k] for o in odds) for k in ("on_mirror", "runs")]
    mirrored = {name: 100 * f["mirrored_share"]["median"] for name, f in families.items()}
    above = ", ".join(f"{name} {share:.1f} %" for name, share in mirrored.items() if share > 0.5)
    worst_mirrored = 100 * max(f["mirrored_share"]["worst"] for f in families.values())
    kidnaps = [(name, families[name]["reconverge_s"]) for name in ("kidnap", "kidnap_special")]
    kidnap_met = all(r["median"] is not None and r["median"] <= 5 for _, r in kidnaps)
    kidnap_all = kidnap_met and all(r["never"] == 0 and r["worst"] is not None and r["worst"] <= 15 for _, r in kidnaps)
    ahead = families["collision"]["reconverge_strong_excess_s"]
    fail_median = {name: 100 * f["fail_share"]["median"] for name, f in families.items()}
    fail_worst = {name: 100 * f["fail_share"]["worst"] for name, f in families.items()}
    over = ", ".join(f"{name} {share:.1f}" for name, share in fail_median.items() if share > 3)
    position = [f["rmse_position_m"]["median"] for f in families.values()]
    heading = [f["rmse_heading_deg"]["median"] for f in families.values()]

    def level(key: str, digits: int) -> str:
        return f"{100 * pooled[key]['share']:.{digits}f} % (with view {100 * view[key]['share']:.{digits}f} %)"

    def met(flag: bool) -> str:
        return "yes" if flag else "no"

    rows = [
        "| target | measured | met |",
        "|---|---|---|",
        f"| no run converges on the mirror | {sum(on_mirror.values())} of {runs} runs ("
        + ", ".join(f"{name} {count}" for name, count in on_mirror.items())
        + f"); of the kidnappings, {clear[0]} of the {clear[1]} the robot could tell apart and {even[0]} of the "
        f"{even[1]} it could not | {met(not on_mirror)} |",
        f"| mirrored share ≤ 0.5 % in every family | medians 0 % except {above or 'none'}; worst runs up to "
        f"{worst_mirrored:.0f} % | {met(not above and worst_mirrored <= 0.5)} |",
        "| unannounced kidnap, any heading: re-converged ≤ 5 s median, ≤ 15 s worst, never 0 | "
        + "; ".join(
            f"{name} {r['median']:.2f} s median, {r['never']} of {r['runs']} never"
            if r["never"]
            else f"{name} {r['median']:.2f} s median"
            for name, r in kidnaps
        )
        + f" | {'yes' if kidnap_all else 'median only' if kidnap_met else 'no'} |",
        f"| odometry running ≥ 0.5 m ahead: ≤ 3 s median | {ahead['median']:.2f} s ({ahead['runs']} runs) | "
        f"{met(ahead['median'] is not None and ahead['median'] <= 3)} |",
        f"| fail share ≤ 3 % median and ≤ 10 % worst in every family | median ≤ 3 % in "
        f"{sum(v <= 3 for v in fail_median.values())} of {len(families)}"
        + (f" ({over} %)" if over else "")
        + f"; worst ≤ 10 % in {sum(v <= 10 for v in fail_worst.values())} of {len(families)} | "
        f"{met(not over and all(v <= 10 for v in fail_worst.values()))} |",
        f"| tracking RMSE ≤ 0.08 m and ≤ 1.5° | family medians {min(position):.3f}–{max(position):.3f} m and "
        f"{min(heading):.1f}–{max(heading):.1f}° | {met(max(position) <= 0.08 and max(heading) <= 1.5)} |",
        f"| SUPERB steps more than 0.5 m off ≤ 1 % | {level('SUPERB', 2)} | {met(pooled['SUPERB']['share'] <= 0.01)} |",
        f"| OKAY steps more than 0.5 m off ≤ 5 % | {level('OKAY', 1)} | {met(pooled['OKAY']['share'] <= 0.05)} |",
        f"| SUPERB covers ≥ 60 % of the steps within 0.3 m | {level('superb_coverage', 1)} | "
        f"{met(pooled['superb_coverage']['share'] >= 0.6)} |",
        f"| `is_lost` recall ≥ 90 % | {level('recall', 1)} | {met(pooled['recall']['share'] >= 0.9)} |",
        f"| `is_lost` false alarms ≤ 2 % | {level('false_alarm', 2)} | {met(pooled['false_alarm']['share'] <= 0.02)} |",
    ]
    return "\n".join(rows)


def fuzz_targets() -> str:
    """The full fuzz run per target (results/fuzz_full.json), as `tests/fuzz_run.py` prints it."""
    d = _load("fuzz_full.json")
    lines = [
        f"fuzz profile {d['profile']}, seed {d['seed']}",
        f"{'target':<22} {'cases':>7} {'accepted':>9} {'refused':>9} {'seconds':>8}  result",
    ]
    for t in d["targets"]:
        result = "ok" if not (t["failure"] or t["crash"]) else ("crash" if t["crash"] else "FAILED")
        lines.append(
            f"{t['target']:<22} {t['cases']:>7} {t['accepted']:>9} {t['refused']:>9} {t['seconds']:>8.1f}  {result}"
        )
    lines.append(
        f"{'total':<22} {d['cases']:>7} {'':>29} {d['seconds']:.1f} s; {d['crashes']} crashes, {d['failures']} failures"
    )
    return "```text\n" + "\n".join(lines) + "\n```"


def soak_minutes() -> str:
    """The soak's minute-by-minute table and its verdict (results/soak.json), in the command's own format."""
    if str(ROOT) not in sys.path:  # the soak's own formatter, in the harness beside the docs (benchmarks/)
        sys.path.insert(0, str(ROOT))
    from benchmarks.soak import table_header, table_row

    d = _load("soak.json")
    lines = [table_header()] + [table_row(row) for row in d["minutes"]] + [d["verdict"]["text"]]
    return "```text\n" + "\n".join(lines) + "\n```"


def recording_size() -> str:
    """The walk demo's recording before and after the recorder's changes (results/recording_stats*.json)."""
    rows = [
        "| | size per minute | chunks (`rerun rrd stats`) | temporal chunks | optimization check |",
        "|---|---|---|---|---|",
    ]
    for label, name in (("before", "recording_stats_before.json"), ("after", "recording_stats.json")):
        d = _load(name)
        stats = d["rrd_stats"]
        check = (
            f'"may be unoptimized" ({stats["effective_chunks"]} chunks against a lower bound of '
            f"{stats['lower_bound_chunks']})"
            if stats["unoptimized_warning"]
            else f"no warning ({stats['effective_chunks']} chunks, the lower bound {stats['lower_bound_chunks']})"
        )
        rows.append(
            f"| {label} (results/{name}, at {d['revision']}) | {d['mib_per_minute']:.2f} MiB | "
            f"{d['chunks']['total']} | {d['chunks']['temporal']} | {check} |"
        )
    return "\n".join(rows)


def _figure(value, kind: str) -> str:
    if value is None:
        return "–"
    return {
        "share": f"{100 * value:.1f} %",
        "m": f"{value:.3f}",
        "count": f"{value}",
        "loss": f"{value:.4f}",
        "evidence": f"{value:.3f}",
    }[kind]


TUNING_ROWS = (
    ("fail share (mean over runs)", "fail_share", "share"),
    ("RMSE position [m]", "rmse_position_m", "m"),
    ("SUPERB wrong", "superb_wrong", "share"),
    ("runs that never re-converged", "never", "count"),
    ("truth loss (the objective)", "truth_loss", "loss"),
    ("log evidence per frame", "evidence_per_frame", "evidence"),
)


def _tuning_table(name: str) -> str:
    """Defaults against the tuned profile, on the training and the held-out cases of a tune results file."""
    comparison = _load(name)["comparison"]
    rows = [
        "| | training, defaults | training, tuned | held-out, defaults | held-out, tuned |",
        "|---|---|---|---|---|",
    ]
    for label, key, kind in TUNING_ROWS:
        cells = [
            _figure(comparison[split][which].get(key), kind)
            for split in ("training", "holdout")
            for which in ("default", "tuned")
        ]
        rows.append(f"| {label} | " + " | ".join(cells) + " |")
    return "\n".join(rows)


def tuning_battery() -> str:
    """`robocup-mcl tune --battery` (results/tune_battery.json)."""
    return _tuning_table("tune_battery.json")


def tuning_battery_8() -> str:
    """`robocup-mcl tune --battery 8` (results/tune_battery_8.json)."""
    return _tuning_table("tune_battery_8.json")


def tuning_venue() -> str:
    """The venue's logs tuned by their evidence (results/tune_venue.json)."""
    return _tuning_table("tune_venue.json")


def tuning_scaling() -> str:
    """`robocup-mcl bench tune` (results/tune_scaling.json)."""
    r = _load("tune_scaling.json")
    one, two, o = r["one_worker"], r["two_workers"], r["overhead"]
    rows = [
        "| figure | measured |",
        "|---|---|",
        f"| trials per hour, 1 worker | {one['trials_per_hour']:.0f} |",
        f"| trials per hour, 2 workers | {two['trials_per_hour']:.0f} |",
        f"| speed-up | {r['speedup']:.2f}× (the same trials and values: {r['same_study']}) |",
        f"| tasks per trial (the task graph) | {r['tasks_per_trial']} |",
        f"| a task, median | {two['task_s_median']:.2f} s |",
        f"| Ray's overhead per task | {1000 * o['overhead_s']:.1f} ms = {100 * o['overhead_share']:.1f} % of the task |",
    ]
    for cores, p in r["projection"].items():
        rows.append(
            f"| projected, {cores} cores ({p['parallel_trials']} trial(s) in flight) | "
            f"{p['trials_per_hour']:.0f} trials per hour; 100 trials in {60 * p['hours_for_100_trials']:.1f} min |"
        )
    return "\n".join(rows)


TEAM_FAMILIES = ("kidnap_even_team", "kidnap_even_wrong", "kidnap_even_silent")


def _team_figures(split: dict) -> dict:
    """The team issue's figures of one split of results/eval_team.json."""
    families = {name: entry["summary"] for name, entry in split["families"].items()}
    runs = {name: entry["runs"] for name, entry in split["families"].items()}
    clear = [
        (name, f["kidnap_odds"]["clear"])
        for name, f in families.items()
        if f.get("kidnap_odds") and f["kidnap_odds"]["clear"]["runs"]
    ]
    recall = [sum(c["pooled"]["recall"][k] for _, c in clear) for k in ("lost", "steps")]
    alarms = [sum(c["pooled"]["false_alarm"][k] for _, c in clear) for k in ("lost", "steps")]
    team = families["kidnap_even_team"]["kidnap_odds"]["even"]
    silent = families["kidnap_even_silent"]["kidnap_odds"]["even"]
    superb = [(name, f["wrong_by_run"]["SUPERB"]) for name, f in families.items()]
    okay = [(name, f["wrong_by_run"]["OKAY"]) for name, f in families.items()]
    every = [r for rs in runs.values() for r in rs]
    return {
        "clear_on_mirror": (
            sum(c["on_mirror"] for _, c in clear),
            sum(c["runs"] for _, c in clear),
            ", ".join(f"{name} {c['on_mirror']}/{c['runs']}" for name, c in clear),
        ),
        "recall": recall,
        "alarms": alarms,
        "team_ends": (team["ends_on_mirror"], team["runs"]),
        "team_correct": team["correct_2s_s"],
        "wrong_flips": families["kidnap_even_wrong"]["flips_to_mirror"],
        "silent_doubted": (silent["mirror_steps_doubted"], silent["mirror_steps"]),
        "superb_runs": (sum(w["over_1"] for _, w in superb), sum(w["runs"] for _, w in superb)),
        "okay_runs": (sum(w["over_5"] for _, w in okay), sum(w["runs"] for _, w in okay)),
        "fail_median": max(f["fail_share"]["median"] for f in families.values()),
        "fail_worst": max(f["fail_share"]["worst"] for f in families.values()),
        "rmse": max(f["rmse_position_m"]["median"] for f in families.values()),
        "runs": len(every),
    }


def team_targets() -> str:
    """The team issue's targets, training and held-out seeds (results/eval_team.json)."""
    splits = _load("eval_team.json")["splits"]
    figures = {name: _team_figures(splits[name]) for name in ("train", "holdout")}

    def share(pair) -> str:
        return "–" if not pair[1] else f"{100 * pair[0] / pair[1]:.1f} % ({pair[0]} of {pair[1]})"

    def seconds(value) -> str:
        return "never" if value is None else f"{value:.2f} s"

    def cell(f: dict, key: str) -> str:
        if key == "clear":
            return f"{f['clear_on_mirror'][0]} of {f['clear_on_mirror'][1]} ({f['clear_on_mirror'][2]})"
        if key == "recall":
            return f"{share(f['recall'])}; false alarms {share(f['alarms'])}"
        if key == "team":
            c = f["team_correct"]
            return (
                f"ends on the mirror {f['team_ends'][0]} of {f['team_ends'][1]}; to 2 s correct median "
                f"{seconds(c['median'])}, worst {seconds(c['worst'])} ({c['never']} never)"
            )
        if key == "wrong":
            return f"{f['wrong_flips']} flips onto the mirror"
        if key == "silent":
            return share(f["silent_doubted"])
        if key == "quality":
            return (
                f"runs with SUPERB > 1 % off: {f['superb_runs'][0]} of {f['superb_runs'][1]}; OKAY > 5 % off: "
                f"{f['okay_runs'][0]} of {f['okay_runs'][1]}"
            )
        if key == "fail":
            return (
                f"largest family median {100 * f['fail_median']:.1f} %, worst run {100 * f['fail_worst']:.0f} %; "
                f"RMSE up to {f['rmse']:.3f} m"
            )
        raise KeyError(key)

    rows = ["| target | training seeds 0–19 | held-out seeds 1000–1019 |", "|---|---|---|"]
    for label, key in (
        ("clear kidnappings: 0 runs on the mirror", "clear"),
        ("clear kidnappings: `is_lost` recall ≥ 90 %, false alarms ≤ 2 %", "recall"),
        ("even kidnappings with the team: ≤ 5 % end on the mirror; to 2 s correct median ≤ 5 s, worst ≤ 20 s", "team"),
        ("a wrong teammate flips no run onto the mirror", "wrong"),
        ("even, no messages: on the mirror from 2 s after, UNSURE_HALF or lost ≥ 90 %", "silent"),
        ("every run: SUPERB > 0.5 m off ≤ 1 %, OKAY ≤ 5 %", "quality"),
        ("fail share median ≤ 2 %, worst ≤ 10 %, every family; RMSE ≤ 0.06 m", "fail"),
    ):
        rows.append(f"| {label} | {cell(figures['train'], key)} | {cell(figures['holdout'], key)} |")
    return "\n".join(rows)


def team_families() -> str:
    """Per family, held-out seeds (results/eval_team.json): fail share, runs on the mirror, side changes."""
    families = _load("eval_team.json")["splits"]["holdout"]["families"]
    rows = [
        "| family | fail share median / worst | runs on the mirror (≥ 2 s) | end on the mirror | side changes by "
        "the team (onto the mirror) | RMSE m |",
        "|---|---|---|---|---|---|",
    ]
    for name, entry in families.items():
        f = entry["summary"]
        ends = sum(bool(r.get("ends_on_mirror")) for r in entry["runs"])
        rmse = "–" if f["rmse_position_m"]["median"] is None else f"{f['rmse_position_m']['median']:.3f}"
        rows.append(
            f"| {name} | {100 * f['fail_share']['median']:.1f} / {100 * f['fail_share']['worst']:.0f} % | "
            f"{f['on_mirror']} | {ends} | {f['team_flips']} ({f['flips_to_mirror']}) | {rmse} |"
        )
    return "\n".join(rows)


def team_cost() -> str:
    """What the team costs in the loop (results/bench_team.json, `robocup-mcl bench team`)."""
    bench = _load("bench_team.json")
    loop = bench["loop_step_us"]
    return "\n".join(
        [
            "| | median | 99th percentile |",
            "|---|---|---|",
            f"| the battery's loop per step, {bench['particles']} particles, without messages | "
            f"{loop['without_messages']:.1f} µs | |",
            f"| the same with the team's messages and the ball ({loop['ratio']:.2f}x) | {loop['with_team']:.1f} µs | |",
            f"| one `team_message` | {bench['team_message']['median_us']:.1f} µs | {bench['team_message']['p99_us']:.1f} µs |",
            f"| one `observe_ball` | {bench['observe_ball']['median_us']:.1f} µs | {bench['observe_ball']['p99_us']:.1f} µs |",
        ]
    )


def team_variant() -> str:
    """The old kidnapping families with the team fed (results/eval_team_on.json, a variant) beside the same runs
    without it (results/eval_team.json)."""
    fed, plain = _load("eval_team_on.json")["splits"], _load("eval_team.json")["splits"]
    rows = [
        "| seeds | family | runs on the mirror (≥ 2 s): without / with the team | end on the mirror | "
        "side changes by the team (onto the mirror) |",
        "|---|---|---|---|---|",
    ]
    for split, label in (("train", "training 0–19"), ("holdout", "held-out 1000–1019")):
        for name, entry in fed[split]["families"].items():
            with_team, without = entry, plain[split]["families"][name]
            ends = [sum(bool(r.get("ends_on_mirror")) for r in e["runs"]) for e in (without, with_team)]
            f = with_team["summary"]
            rows.append(
                f"| {label} | {name} | {without['summary']['on_mirror']} / {f['on_mirror']} | "
                f"{ends[0]} / {ends[1]} | {f['team_flips']} ({f['flips_to_mirror']}) |"
            )
    return "\n".join(rows)


def _on_path() -> None:
    """The repository's own packages first on sys.path (a build from another directory, or an environment whose
    editable install points at another checkout, still documents and measures this tree)."""
    if sys.path[:1] != [str(ROOT)]:
        sys.path.insert(0, str(ROOT))


# What a team's behaviour should do at each signal of the localizer (docs/acting.md). The measured figures
# beside them are read from results/eval_team.json.
ACTIONS = {
    "SUPERB": "play: kick, shoot at goal, pass to a position",
    "OKAY": "walk to the ball and position; look at landmarks when the head is free; avoid shots that need an "
    "exact angle",
    "UNSURE_HALF": "do not shoot or dribble toward a goal; look at the ball (it decides the half); read "
    "`hypotheses()` and ask the team",
    "POOR": "do not plan on the pose: stop walking to field positions, scan with the head for landmarks",
    "is_lost": "stop, turn the head and then the body to look around; tell the team; wait for a game event or "
    "for the quality to come back",
    "hypotheses": "when `mirror` weighs about as much as `main`, pick by the ball: the half where the own ball "
    "sighting agrees with the teammates'; when a `rival` does, look at the landmarks that tell the two apart; "
    "show them to the team",
}
TEAM_COMMAND = "robocup-mcl eval --split both --seeds 20 --save results/eval_team.json"


def _count(n: int) -> str:
    """12345 -> '12 345'."""
    return f"{n:,}".replace(",", " ")


def acting_levels() -> str:
    """Each quality level, `is_lost` and the hypotheses with their measured error rates on the held-out seeds of
    the battery (results/eval_team.json, every family) and what a behaviour should do."""
    results = _load("eval_team.json")
    split = results["splits"]["holdout"]
    pooled = split["overall"]["pooled"]
    total = sum(pooled[level]["steps"] for level in ("SUPERB", "OKAY", "UNSURE_HALF", "POOR"))
    seeds = split["seeds"]
    rows = [
        f"Pooled over the {split['overall']['runs']} held-out runs of `results/eval_team.json` "
        f"({len(split['families'])} families, seeds {min(seeds)}–{max(seeds)}, {results['duration_s']:g} s each, "
        f"{results['particles']} particles, detections {'with' if results['view'] else 'without'} the camera's "
        f"view; `{TEAM_COMMAND}`), each step sampled after the 100 Hz motion step:",
        "",
        "| signal | share of the steps | measured on the held-out battery | what the behaviour should do |",
        "|---|---|---|---|",
    ]
    for level in ("SUPERB", "OKAY", "UNSURE_HALF", "POOR"):
        p = pooled[level]
        rows.append(
            f"| `Quality.{level}` | {100 * p['steps'] / total:.1f} % | {100 * p['share']:.2f} % of its "
            f"steps more than 0.5 m off ({_count(p['wrong'])} of {_count(p['steps'])}) | {ACTIONS[level]} |"
        )
    recall, alarm = pooled["recall"], pooled["false_alarm"]
    rows.append(
        f"| `is_lost` | | "
        f"set on {100 * recall['share']:.1f} % of the steps more than 1 m off, from 2 s into such an "
        f"episode (recall: {_count(recall['lost'])} of {_count(recall['steps'])}); on "
        f"{100 * alarm['share']:.2f} % of the steps within 0.3 m (false alarms) | "
        f"{ACTIONS['is_lost']} |"
    )
    silent = split["families"]["kidnap_even_silent"]["summary"]["kidnap_odds"]["even"]
    rows.append(
        f"| `hypotheses()` | | after kidnappings that nothing sensed tells apart, without teammates "
        f"(`kidnap_even_silent`): {silent['ends_on_mirror']} of {silent['runs']} runs end on the mirror; "
        f"on {100 * silent['mirror_steps_doubted'] / silent['mirror_steps']:.1f} % of the steps on the "
        f"mirror the quality said UNSURE_HALF or POOR | {ACTIONS['hypotheses']} |"
    )
    return "\n".join(rows)


def _threshold_help() -> dict[str, str]:
    """The description of each `QualityThresholds` field, from its docstring's Attributes section."""
    _on_path()
    from mcl.localizer import QualityThresholds

    doc = QualityThresholds.__doc__ or ""
    attributes = doc.split("Attributes\n    ----------\n", 1)[1].split("\n\n", 1)[0]
    out: dict[str, str] = {}
    names: list[str] = []
    for line in attributes.splitlines():
        if line.startswith("    ") and not line.startswith("        "):
            names = [n.strip() for n in line.split(" : ", 1)[0].split(",")]
        elif line.strip():
            for name in names:
                out[name] = (out.get(name, "") + " " + line.strip()).strip()
    return out


def acting_thresholds() -> str:
    """The limits that decide the quality, `QualityThresholds`' own defaults (read from the class), in one table:
    a SUPERB and an OKAY column where the field comes in pairs."""
    _on_path()
    import dataclasses

    from mcl.localizer import QualityThresholds

    # a default made by a factory (the rival places' `RivalSettings`) is shown by its class's name
    defaults = {
        f.name: f.default if f.default is not dataclasses.MISSING else f"{f.default_factory.__name__}()"  # type: ignore[misc]
        for f in dataclasses.fields(QualityThresholds)
    }
    described = _threshold_help()
    rows = ["| limit | SUPERB | OKAY | meaning |", "|---|---|---|---|"]
    done = set()
    for name in defaults:
        if name in done:
            continue
        if name.startswith(("superb_", "okay_")):
            stem = name.split("_", 1)[1]
            superb, okay = f"superb_{stem}", f"okay_{stem}"
            cells = [f"`{n}` = {defaults[n]:g}" if n in defaults else "–" for n in (superb, okay)]
            done.update((superb, okay))
            text = described.get(superb) or described.get(okay, "")
            rows.append(f"| {stem} | {cells[0]} | {cells[1]} | {text} |")
        else:
            done.add(name)
            value = defaults[name] if isinstance(defaults[name], str) else f"{defaults[name]:g}"
            rows.append(f"| {name} | `{name}` = {value} (every level) | | {described.get(name, '')} |")
    return "\n".join(rows)


# The API reference: one page per module of these packages.
API_PACKAGES = ("mcl", "motion_models", "sensing", "proprioception", "field", "numerics")


def _summary(path: Path) -> str:
    """The first sentence-line of a module's docstring (for the package pages' tables)."""
    doc = ast.get_docstring(ast.parse(path.read_text(encoding="utf-8"))) or ""
    first = doc.strip().split("\n\n", 1)[0].replace("\n", " ")
    return first.replace("|", "\\|")


def api_tree(package: str = "", path: Path | None = None) -> list[tuple[str, Path, list]]:
    """(dotted name, source path, children) for each package of `API_PACKAGES` (or below `package`): packages
    with their public modules and subpackages, sorted by name."""
    if not package:
        return [(name, ROOT / name / "__init__.py", api_tree(name, ROOT / name)) for name in API_PACKAGES]
    out = []
    for entry in sorted(path.iterdir()):
        if entry.name.startswith(("_", ".")):
            continue
        if entry.is_dir() and (entry / "__init__.py").exists():
            out.append((f"{package}.{entry.name}", entry / "__init__.py", api_tree(f"{package}.{entry.name}", entry)))
        elif entry.suffix == ".py":
            out.append((f"{package}.{entry.stem}", entry, []))
    return out


def api_uri(name: str) -> str:
    """`mcl.tools.cli` -> `api/mcl/tools/cli.md`."""
    return "api/" + name.replace(".", "/") + ".md"


def api_pages() -> dict[str, str]:
    """The markdown of every API page, by its path in the docs."""
    pages: dict[str, str] = {}

    def walk(name: str, path: Path, children: list) -> None:
        if children or path.name == "__init__.py":
            here = api_uri(name)
            rows = ["| module | |", "|---|---|"]
            for child, child_path, _ in children:
                link = Path(api_uri(child)).relative_to(Path(here).parent).as_posix()
                rows.append(f"| [`{child}`]({link}) | {_summary(child_path)} |")
            pages[here] = (
                f"# `{name}`\n\n::: {name}\n    options:\n      show_root_heading: false\n"
                f"      members: false\n\n## Modules\n\n" + "\n".join(rows) + "\n"
            )
            for child in children:
                walk(*child)
        else:
            pages[api_uri(name)] = f"# `{name}`\n\n::: {name}\n    options:\n      show_root_heading: false\n"

    for package in api_tree():
        walk(*package)
    return pages


def api_nav() -> list:
    """The navigation's API section: each package's page, then its modules (subpackages as sections)."""

    def entry(name: str, children: list):
        if not children:
            return {name: api_uri(name)}
        return {name: [api_uri(name)] + [entry(child, grand) for child, _, grand in children]}

    return [entry(name, children) for name, _, children in api_tree()]


def on_config(config):
    """The snippets' base path is the repository root whatever the current directory; the API section of the
    navigation is the generated pages."""
    snippets = config.mdx_configs.setdefault("pymdownx.snippets", {})
    snippets["base_path"] = [str(ROOT)]
    for item in config.nav or []:
        if isinstance(item, dict) and "API reference" in item:
            item["API reference"] = api_nav()
    return config


def on_files(files, config):
    """Adds the generated API pages."""
    from mkdocs.structure.files import File

    for uri, text in api_pages().items():
        files.append(File.generated(config, uri, content=text))
    return files


ARITHMATEX = re.compile(r'<(span|div) class="arithmatex">(.*?)</\1>', flags=re.S)


def tex_to_mathml(page_html: str) -> str:
    """pymdownx.arithmatex's `\\(...\\)` and `\\[...\\]` as MathML (rendered by the browser, no script)."""
    from latex2mathml.converter import convert

    def one(match: re.Match) -> str:
        tex = html.unescape(match.group(2)).strip()
        block = match.group(1) == "div"
        tex = tex[2:-2] if tex[:2] in ("\\(", "\\[") else tex
        return convert(tex.strip(), display="block" if block else "inline")

    return ARITHMATEX.sub(one, page_html)


# A code block without a language: mkdocstrings leaves it plain (`<pre><code>`), or highlighted as text (no
# token spans inside).
PLAIN_CODE = re.compile(
    r'(?:<div class="highlight"><pre><span></span><code>((?:(?!<span|</code>).)*)</code></pre></div>'
    r"|<pre><code>((?:(?!<span|</code>).)*)</code></pre>)",
    flags=re.S,
)


def highlight_docstring_code(page_html: str) -> str:
    """The docstrings' code blocks (reST literal blocks after `::`, markdown's indented blocks), which
    mkdocstrings leaves plain, highlighted as Python like the pages' fenced blocks; `Example::` reads
    `Example:`."""
    from pygments import highlight
    from pygments.formatters import HtmlFormatter
    from pygments.lexers import PythonLexer

    def one(match: re.Match) -> str:
        plain = match.group(1) if match.group(1) is not None else match.group(2)
        code = highlight(html.unescape(plain), PythonLexer(), HtmlFormatter(nowrap=True))
        return f'<div class="highlight"><pre><span></span><code>{code}</code></pre></div>'

    return PLAIN_CODE.sub(one, page_html).replace("::</p>", ":</p>")


def on_page_content(page_html: str, page, config, files) -> str:  # noqa: ARG001 (mkdocs' hook signature)
    """TeX to MathML on every page; the API pages' docstring code highlighted."""
    page_html = tex_to_mathml(page_html)
    if page.file.src_uri.startswith("api/"):
        page_html = highlight_docstring_code(page_html)
    return page_html


TABLES = {
    "battery-families": battery_families,
    "battery-quality": battery_quality,
    "recording-size": recording_size,
    "battery-targets": battery_targets,
    "fuzz-targets": fuzz_targets,
    "soak-minutes": soak_minutes,
    "tuning-battery": tuning_battery,
    "tuning-battery-8": tuning_battery_8,
    "tuning-venue": tuning_venue,
    "tuning-scaling": tuning_scaling,
    "team-targets": team_targets,
    "team-families": team_families,
    "team-cost": team_cost,
    "team-variant": team_variant,
    "acting-levels": acting_levels,
    "acting-thresholds": acting_thresholds,
}
MARKER = re.compile(r"^<!-- results-table: ([\w-]+) -->$", flags=re.M)


def results_tables(markdown: str) -> str:
    """Replace each results-table marker with its table (KeyError for an unknown name)."""
    return MARKER.sub(lambda match: TABLES[match.group(1)](), markdown)


def on_page_markdown(markdown: str, page, config, files) -> str:  # noqa: ARG001 (mkdocs' hook signature)
    """The home page's placeholder becomes the README; results-table markers become their tables."""
    if page.file.src_uri == "index.md":
        return readme_as_home()
    return results_tables(markdown)
