"""Build hooks of the documentation site (mkdocs.yml `hooks:`).

The home page is the README: `index.md` holds one line, and this hook puts the README in its place with its
links made relative to the docs folder, so the two never differ.

Tables from results files: a line `<!-- results-table: NAME -->` in a page is replaced by the table `NAME`
built from the JSON files the commands wrote (`TABLES`), so a new measurement changes the page when the site is
built. A missing file or key fails the build.
"""
from __future__ import annotations

import json
import re
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
    rows = ["| family | re-converge [s], detections only | with view | fail share, detections only | with view "
            "| on the mirror | RMSE m / °, detections only |", "|---|---|---|---|---|---|---|"]
    for family, entry in plain.items():
        a, b = entry["summary"], view[family]["summary"]
        rows.append(f"| {family} | {_seconds(a['reconverge_s'])} | {_seconds(b['reconverge_s'])} | "
                    f"{100 * a['fail_share']['median']:.1f} / {100 * a['fail_share']['worst']:.0f} % | "
                    f"{100 * b['fail_share']['median']:.1f} / {100 * b['fail_share']['worst']:.0f} % | "
                    f"{a['on_mirror']} / {b['on_mirror']} | "
                    f"{a['rmse_position_m']['median']:.3f} / {a['rmse_heading_deg']['median']:.1f} |")
    return "\n".join(rows)


def battery_quality() -> str:
    """The quality signal pooled over every held-out step, detections only and with the view."""
    plain = _load("eval_holdout.json")["splits"]["holdout"]["overall"]["pooled"]
    view = _load("eval_holdout_view.json")["splits"]["holdout"]["overall"]["pooled"]
    lines = [("SUPERB steps more than 0.5 m off", "SUPERB", 2), ("OKAY steps more than 0.5 m off", "OKAY", 1),
             ("SUPERB coverage of the steps within 0.3 m", "superb_coverage", 1), ("`is_lost` recall", "recall", 1),
             ("`is_lost` false alarms", "false_alarm", 2)]
    rows = ["| | detections only | with view |", "|---|---|---|"]
    rows += [f"| {label} | {100 * plain[key]['share']:.{digits}f} % | {100 * view[key]['share']:.{digits}f} % |"
             for label, key, digits in lines]
    return "\n".join(rows)


def recording_size() -> str:
    """The walk demo's recording before and after the recorder's changes (results/recording_stats*.json)."""
    rows = ["| | size per minute | chunks (`rerun rrd stats`) | temporal chunks | optimization check |",
            "|---|---|---|---|---|"]
    for label, name in (("before", "recording_stats_before.json"), ("after", "recording_stats.json")):
        d = _load(name)
        stats = d["rrd_stats"]
        check = (f"\"may be unoptimized\" ({stats['effective_chunks']} chunks against a lower bound of "
                 f"{stats['lower_bound_chunks']})" if stats["unoptimized_warning"]
                 else f"no warning ({stats['effective_chunks']} chunks, the lower bound {stats['lower_bound_chunks']})")
        rows.append(f"| {label} (results/{name}, at {d['revision']}) | {d['mib_per_minute']:.2f} MiB | "
                    f"{d['chunks']['total']} | {d['chunks']['temporal']} | {check} |")
    return "\n".join(rows)


TABLES = {"battery-families": battery_families, "battery-quality": battery_quality,
          "recording-size": recording_size}
MARKER = re.compile(r"^<!-- results-table: ([\w-]+) -->$", flags=re.M)


def results_tables(markdown: str) -> str:
    """Replace each results-table marker with its table (KeyError for an unknown name)."""
    return MARKER.sub(lambda match: TABLES[match.group(1)](), markdown)


def on_page_markdown(markdown: str, page, config, files) -> str:   # noqa: ARG001 (mkdocs' hook signature)
    """The home page's placeholder becomes the README; results-table markers become their tables."""
    if page.file.src_uri == "index.md":
        return readme_as_home()
    return results_tables(markdown)
