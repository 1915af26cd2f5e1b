"""The README's integration example runs as written and finds the pose its detections describe."""
import contextlib
import io
import math
import re
from pathlib import Path

README = Path(__file__).resolve().parent.parent / "README.md"


def python_blocks():
    return re.findall(r"```python\n(.*?)```", README.read_text(), flags=re.S)


def test_integration_example_runs_and_localizes():
    example = next(block for block in python_blocks() if "ParticleFilter" in block)
    assert len(example.strip().splitlines()) <= 15
    namespace: dict = {}
    with contextlib.redirect_stdout(io.StringIO()):
        exec(compile(example, str(README), "exec"), namespace)
    pose = namespace["est"].pose
    assert math.hypot(pose[0] + 2.0, pose[1]) < 0.05
    assert abs(math.remainder(pose[2] - math.pi, 2 * math.pi)) < 0.03
    h = namespace["h"]
    assert 0 <= h.position and 0 <= h.orientation


def test_readme_quick_start_has_exactly_the_two_commands():
    quick = README.read_text().split("## Quick start", 1)[1].split("##", 1)[0]
    block = re.search(r"```sh\n(.*?)```", quick, flags=re.S).group(1).strip().splitlines()
    assert block == ["make demo", "make test"]


def test_lwpr_example_runs_and_learns():
    example = next(block for block in python_blocks() if "LWPR(2, 1)" in block)
    namespace: dict = {}
    exec(compile(example, str(README), "exec"), namespace)
    assert abs(namespace["y_hat"][0] - (-0.1567)) < 0.02 and namespace["conf"][0] > 0


def test_localizer_example_runs_and_starts_on_a_touchline():
    example = next(block for block in python_blocks() if "Localizer(" in block)
    namespace: dict = {}
    with contextlib.redirect_stdout(io.StringIO()):
        exec(compile(example, str(README), "exec"), namespace)
    field, pose = namespace["loc"].field, namespace["estimate"].pose
    assert abs(abs(pose[1]) - field.half_width) < 0.3 and pose[0] < 0
    assert abs(abs(pose[2]) - math.pi / 2) < 0.3
