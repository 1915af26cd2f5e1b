"""The fuzz suite's CI profile: every target in child processes (`tests/fuzz_run.py --profile ci`), a fixed set
of generated cases, its counts printed. `make fuzz` runs the full profile (fresh cases, >= 10 000)."""

import json
import subprocess
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
REPORT: list[str] = []  # the runner's table, printed at the end of the session (tests/conftest.py)


def test_the_fuzz_suite_ci_profile_finds_nothing(tmp_path):
    out = tmp_path / "fuzz.json"
    process = subprocess.run(
        [sys.executable, str(HERE / "fuzz_run.py"), "--profile", "ci", "--save", str(out)],
        capture_output=True,
        text=True,
        cwd=HERE.parent,
    )
    REPORT[:] = [line for line in process.stdout.splitlines() if line.strip()][:12]
    assert process.returncode == 0, process.stdout[-6000:] + process.stderr[-3000:]
    summary = json.loads(out.read_text())
    assert summary["crashes"] == 0 and summary["failures"] == 0
    assert summary["cases"] >= 2000
    for target in summary["targets"]:
        assert target["cases"] > 0 and target["refused"] > 0, target  # each target reaches its entry points
        assert target["accepted"] > 0, target


def test_the_runner_reports_a_crash_with_its_case(tmp_path, monkeypatch):
    """A target whose process dies is reported as a crash naming the case it ran, and the run goes on."""
    sys.path.insert(0, str(HERE))
    import fuzz_run

    result = fuzz_run.run_target("_crash", 5, True, None)
    assert result["crash"] and "killed by SIGSEGV" in result["crash"] and "_crash: " in result["crash"]
    assert result["failure"] is None
