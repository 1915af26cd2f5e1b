"""The README and the documentation pages: their examples run as written and do what the text says, the Quick
start has exactly its two commands, and the README stays a front door (at most 15 KB)."""
import contextlib
import io
import math
import re
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
README = ROOT / "README.md"
DOCS = ROOT / "docs"


def python_blocks(path: Path = README):
    return re.findall(r"```python\n(.*?)```", path.read_text(), flags=re.S)


def run(path: Path, marker: str, quiet: bool = True) -> dict:
    """Run the first Python block of `path` that contains `marker`; its namespace."""
    example = next(block for block in python_blocks(path) if marker in block)
    namespace: dict = {}
    with contextlib.redirect_stdout(io.StringIO()) if quiet else contextlib.nullcontext():
        exec(compile(example, str(path), "exec"), namespace)
    return namespace


def test_integration_example_runs_and_localizes():
    example = next(block for block in python_blocks() if "ParticleFilter" in block)
    assert len(example.strip().splitlines()) <= 15
    namespace = run(README, "ParticleFilter")
    pose = namespace["est"].pose
    assert math.hypot(pose[0] + 2.0, pose[1]) < 0.05
    assert abs(math.remainder(pose[2] - math.pi, 2 * math.pi)) < 0.03
    h = namespace["h"]
    assert 0 <= h.position and 0 <= h.orientation


def test_the_readme_and_the_integration_page_hold_the_same_robot_loop():
    loop = next(block for block in python_blocks() if "ParticleFilter" in block)
    assert loop in python_blocks(DOCS / "integration.md")


def test_readme_quick_start_has_exactly_the_two_commands():
    quick = README.read_text().split("## Quick start", 1)[1].split("##", 1)[0]
    block = re.search(r"```sh\n(.*?)```", quick, flags=re.S).group(1).strip().splitlines()
    assert block == ["make demo", "make test"]


def test_the_readme_is_a_front_door():
    assert README.stat().st_size <= 15 * 1024
    assert "../shared" not in README.read_text()
    for target in re.findall(r"\]\(([^)#\s]+)", README.read_text()):
        if not re.match(r"https?://", target):
            assert (ROOT / target).exists(), f"the README links to {target}, which is not in the repository"


def test_lwpr_example_runs_and_learns():
    namespace = run(DOCS / "papers" / "rouxel.md", "LWPR(2, 1)", quiet=False)
    assert abs(namespace["y_hat"][0] - (-0.1567)) < 0.02 and namespace["conf"][0] > 0


def test_localizer_example_runs_and_starts_on_a_touchline():
    namespace = run(DOCS / "integration.md", "Localizer(")
    field, pose = namespace["loc"].field, namespace["estimate"].pose
    assert abs(abs(pose[1]) - field.half_width) < 0.3 and pose[0] < 0
    assert abs(abs(pose[2]) - math.pi / 2) < 0.3
