"""The documentation site builds with `mkdocs build --strict`: a dead link, a page left out of the navigation, a
missing anchor or a broken API reference fails the build, and so this test."""
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent

pytest.importorskip("mkdocs", reason="the docs extra is installed by `make test`")


def test_the_site_builds_strict(tmp_path):
    done = subprocess.run([sys.executable, "-m", "mkdocs", "build", "--strict", "--site-dir", str(tmp_path / "site")],
                          cwd=ROOT, capture_output=True, text=True, timeout=900,
                          env={**os.environ, "NO_MKDOCS_2_WARNING": "1"})
    assert done.returncode == 0, done.stderr[-4000:]
    assert (tmp_path / "site" / "index.html").exists()
    api = (tmp_path / "site" / "api" / "mcl" / "index.html").read_text()
    assert "ParticleFilter" in api and "Localizer" in api        # the reference is generated, not empty


def test_no_page_links_outside_the_repository_but_to_public_urls():
    for page in (ROOT / "docs").rglob("*.md"):
        text = page.read_text()
        assert "../shared" not in text, f"{page} points at files outside the repository"
        for target in re.findall(r"\]\(([^)\s]+)\)", text):
            if re.match(r"[a-z]+://", target):
                assert target.startswith("https://"), f"{page}: {target} is not a public https URL"


def _hooks():
    import importlib.util
    spec = importlib.util.spec_from_file_location("docs_hooks", ROOT / "docs" / "hooks.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_results_tables_are_built_from_the_results_files():
    import json
    hooks = _hooks()
    page = "before\n<!-- results-table: battery-families -->\nafter"
    table = hooks.results_tables(page)
    assert "results-table" not in table and table.startswith("before\n| family |") and table.endswith("\nafter")
    kidnap = json.loads((ROOT / "results" / "eval_holdout.json").read_text())["splits"]["holdout"]["families"][
        "kidnap"]["summary"]
    row = next(line for line in table.splitlines() if line.startswith("| kidnap |"))
    assert f"{kidnap['reconverge_s']['median']:.2f} / never, {kidnap['reconverge_s']['never']} never" in row
    with pytest.raises(KeyError):
        hooks.results_tables("<!-- results-table: no-such-table -->")


def test_the_home_page_is_the_readme_with_links_into_docs():
    home = _hooks().readme_as_home()
    assert "](docs/" not in home and "](getting-started.md)" in home and "## Quick start" in home


def test_the_targets_table_says_what_the_results_say():
    import json
    table = _hooks().battery_targets()
    split = json.loads((ROOT / "results" / "eval_holdout.json").read_text())["splits"]["holdout"]
    on_mirror = sum(f["summary"]["on_mirror"] for f in split["families"].values())
    first = next(line for line in table.splitlines() if line.startswith("| no run converges on the mirror"))
    assert f"| {on_mirror} of {split['overall']['runs']} runs" in first and first.endswith(f"| {'no' if on_mirror else 'yes'} |")
    superb = split["overall"]["pooled"]["SUPERB"]["share"]
    row = next(line for line in table.splitlines() if line.startswith("| SUPERB steps"))
    assert f"{100 * superb:.2f} %" in row and row.endswith("| yes |" if superb <= 0.01 else "| no |")


def test_the_reliability_tables_are_those_of_the_results_files():
    import json
    hooks = _hooks()
    fuzz = json.loads((ROOT / "results" / "fuzz_full.json").read_text())
    table = hooks.fuzz_targets()
    assert f"{fuzz['cases']:>7}" in table and f"{fuzz['crashes']} crashes, {fuzz['failures']} failures" in table
    assert len([line for line in table.splitlines() if line.endswith("  ok")]) == len(fuzz["targets"])
    soak = json.loads((ROOT / "results" / "soak.json").read_text())
    minutes = hooks.soak_minutes()
    assert soak["verdict"]["text"] in minutes and len(minutes.splitlines()) == len(soak["minutes"]) + 4


def test_the_team_tables_say_what_the_results_say():
    import json
    hooks = _hooks()
    split = json.loads((ROOT / "results" / "eval_team.json").read_text())["splits"]["holdout"]
    table = hooks.team_targets()
    wrong = split["families"]["kidnap_even_wrong"]["summary"]["flips_to_mirror"]
    row = next(line for line in table.splitlines() if line.startswith("| a wrong teammate"))
    assert row.endswith(f"| {wrong} flips onto the mirror |")
    even = split["families"]["kidnap_even_team"]["summary"]["kidnap_odds"]["even"]
    row = next(line for line in table.splitlines() if line.startswith("| even kidnappings with the team"))
    assert f"ends on the mirror {even['ends_on_mirror']} of {even['runs']}" in row.split("|")[3]
    families = hooks.team_families()
    assert len(families.splitlines()) == 2 + len(split["families"])
    bench = json.loads((ROOT / "results" / "bench_team.json").read_text())
    assert f"{bench['team_message']['median_us']:.1f} µs" in hooks.team_cost()
    variant = hooks.team_variant()
    assert variant.count("\n") == 1 + 4 and "| held-out 1000–1019 | kidnap |" in variant
