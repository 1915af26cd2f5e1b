"""The documentation site builds with `mkdocs build --strict`: a dead link, a page left out of the navigation, a
missing anchor or a broken API reference fails the build, and so this test. The site is built once (from
another directory than the repository's, as a team's script might) and then read: it works offline (no asset
from an outside host), the math is MathML, and the API reference has a page per module."""

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent

pytest.importorskip("mkdocs", reason="the docs extra is installed by `make test`")


@pytest.fixture(scope="module")
def site(tmp_path_factory) -> Path:
    """The site built with --strict from a directory outside the repository (`-f` names the configuration): the
    snippets, the hooks and the API reference must not depend on the current directory."""
    elsewhere = tmp_path_factory.mktemp("elsewhere")
    out = elsewhere / "site"
    done = subprocess.run(
        [sys.executable, "-m", "mkdocs", "build", "--strict", "-f", str(ROOT / "mkdocs.yml"), "--site-dir", str(out)],
        cwd=elsewhere,
        capture_output=True,
        text=True,
        timeout=900,
        env={**os.environ, "NO_MKDOCS_2_WARNING": "1"},
    )
    assert done.returncode == 0, done.stderr[-4000:]
    return out


def test_the_site_builds_strict_from_another_directory(site):
    assert (site / "index.html").exists()
    latency = (site / "integration" / "index.html").read_text()
    assert "--8<--" not in latency and "seed" in latency  # the snippets were found from elsewhere
    filter_page = (site / "api" / "mcl" / "filter" / "index.html").read_text()
    localizer = (site / "api" / "mcl" / "localizer" / "index.html").read_text()
    assert 'id="mcl.filter.ParticleFilter"' in filter_page and 'id="mcl.localizer.Localizer"' in localizer


def test_the_api_reference_has_a_page_per_module_in_the_navigation(site):
    hooks = _hooks()
    pages = hooks.api_pages()
    modules = [
        p.relative_to(ROOT)
        for package in hooks.API_PACKAGES
        for p in (ROOT / package).rglob("*.py")
        if not p.name.startswith("_") and "__pycache__" not in p.parts
    ]
    for module in modules:
        assert f"api/{module.with_suffix('').as_posix()}.md" in pages, f"{module} has no API page"
    assert len(pages) >= len(modules) + len(hooks.API_PACKAGES)
    nav = (site / "index.html").read_text()
    for uri in pages:
        target = uri[:-3] + "/"
        assert f'href="{target}"' in nav, f"{uri} is not in the navigation"
        assert (site / target / "index.html").exists()
    lwpr = (site / "api" / "motion_models" / "lwpr" / "index.html").read_text()
    assert '<span class="kn">import</span>' in lwpr  # its docstring's example, highlighted as Python
    for page in (site / "api").rglob("index.html"):  # no docstring code left plain
        for code in re.findall(r"<pre><span></span><code>(.*?)</code>|<pre><code>(.*?)</code>", page.read_text(), re.S):
            assert "<span" in "".join(code), f"{page.relative_to(site)}: {''.join(code)[:200]}"


def test_the_math_is_mathml_made_at_build_time(site):
    models = (site / "models" / "index.html").read_text()
    assert models.count("<math") >= 20 and "arithmatex" not in models and "\\(" not in models


# Attributes that load something when the page opens (an <a>'s href does not: a reader clicks it).
LOADING = re.compile(r"<(?!a\b)(\w+)\b[^>]*?\s(?:src|href|srcset|data|poster|action)=[\"']?(https?:)?//", re.I)
CSS_URL = re.compile(r"(?:url\(\s*[\"']?|@import\s+[\"']?)(https?:)?//", re.I)
JS_LOAD = re.compile(r"(?:importScripts\(|import\(|\bfrom\s*)[\"'`](https?:)?//", re.I)


def test_the_site_loads_nothing_from_an_outside_host(site):
    """Offline at a venue: no page, stylesheet or script loads anything from another host (scripts, styles,
    fonts, images, frames; `url()` and `@import` in CSS and in inline styles; imports in scripts). Links a
    reader clicks (`<a href>`: the repository, the tools' sites, the papers) are allowed. The theme's
    repository widget, which asks GitHub's API for its figures on each page load, is kept out
    (docs/overrides/partials/source.html)."""
    checked = 0
    for path in site.rglob("*"):
        if path.suffix not in (".html", ".css", ".js"):
            continue
        text = path.read_text(encoding="utf-8", errors="replace")
        checked += 1
        if path.suffix == ".html":
            for match in LOADING.finditer(text):
                pytest.fail(f"{path.relative_to(site)} loads from an outside host: {match.group(0)[:200]}")
            assert 'data-md-component="source"' not in text, f"{path.relative_to(site)}: the GitHub API widget"
        if path.suffix in (".css", ".html"):
            match = CSS_URL.search(text)
            assert match is None, f"{path.relative_to(site)}: {text[match.start() : match.start() + 120]}"
        if path.suffix == ".js":
            match = JS_LOAD.search(text)
            assert match is None, f"{path.relative_to(site)}: {text[match.start() : match.start() + 120]}"
    assert checked > 50


def test_the_outside_host_check_finds_what_it_is_for():
    """The patterns of the check above catch a CDN script, a web font, a stylesheet link and an import, and let
    a reader's link through."""
    assert LOADING.search('<script src="https://unpkg.com/mathjax@3/es5/tex-mml-chtml.js"></script>')
    assert LOADING.search('<link rel="stylesheet" href="https://fonts.googleapis.com/css?family=Roboto">')
    assert LOADING.search('<img alt="x" src="//cdn.example.org/x.png">')
    assert CSS_URL.search("@font-face{src:url(https://fonts.gstatic.com/s/roboto.woff2)}")
    assert CSS_URL.search('@import "https://example.org/a.css";')
    assert JS_LOAD.search('importScripts("https://cdn.example.org/lunr.js")')
    assert not LOADING.search('<a href="https://doi.org/10.1007/978-3-540-32256-6_45">the paper</a>')


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
        "kidnap"
    ]["summary"]
    row = next(line for line in table.splitlines() if line.startswith("| kidnap |"))
    assert f"{kidnap['reconverge_s']['median']:.2f} / never, {kidnap['reconverge_s']['never']} never" in row
    with pytest.raises(KeyError):
        hooks.results_tables("<!-- results-table: no-such-table -->")


def test_the_acting_page_says_what_the_results_and_the_code_say():
    """docs/acting.md's tables: the rates of results/eval_team.json (held-out seeds) and the thresholds of
    `QualityThresholds`' defaults."""
    import dataclasses
    import json

    from mcl.localizer import QualityThresholds

    hooks = _hooks()
    page = (ROOT / "docs" / "acting.md").read_text()
    assert "<!-- results-table: acting-levels -->" in page and "<!-- results-table: acting-thresholds -->" in page
    pooled = json.loads((ROOT / "results" / "eval_team.json").read_text())["splits"]["holdout"]["overall"]["pooled"]
    levels = hooks.acting_levels()
    for level in ("SUPERB", "OKAY", "UNSURE_HALF", "POOR"):
        row = next(line for line in levels.splitlines() if line.startswith(f"| `Quality.{level}` |"))
        assert f"{100 * pooled[level]['share']:.2f} % of its steps" in row
    assert f"set on {100 * pooled['recall']['share']:.1f} % of the steps" in levels
    thresholds = hooks.acting_thresholds()
    for field in dataclasses.fields(QualityThresholds):
        if field.default is dataclasses.MISSING:  # made by a factory: shown by the class's name
            assert f"`{field.name}` = {field.default_factory.__name__}()" in thresholds, field.name
        else:
            assert f"`{field.name}` = {field.default:g}" in thresholds, field.name
    assert len(thresholds.splitlines()) == 2 + len(
        {f.name.removeprefix("superb_").removeprefix("okay_") for f in dataclasses.fields(QualityThresholds)}
    )


def test_the_home_page_is_the_readme_with_links_into_docs():
    home = _hooks().readme_as_home()
    assert "](docs/" not in home and "](getting-started.md)" in home and "## Quick start" in home


def test_the_targets_table_says_what_the_results_say():
    import json

    table = _hooks().battery_targets()
    split = json.loads((ROOT / "results" / "eval_holdout.json").read_text())["splits"]["holdout"]
    on_mirror = sum(f["summary"]["on_mirror"] for f in split["families"].values())
    first = next(line for line in table.splitlines() if line.startswith("| no run converges on the mirror"))
    assert f"| {on_mirror} of {split['overall']['runs']} runs" in first and first.endswith(
        f"| {'no' if on_mirror else 'yes'} |"
    )
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
