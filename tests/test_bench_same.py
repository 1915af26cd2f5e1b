"""`robocup-mcl bench same`: fingerprints of exact bits, wall-clock figures left out, and the comparison's report."""

import numpy as np
import pytest

from benchmarks import same


def test_a_fingerprint_sees_every_bit():
    a = np.array([0.1, 0.2, 0.3])
    b = a.copy()
    b[1] = np.nextafter(b[1], 1.0)  # one unit in the last place
    assert same.digest(a) == same.digest(a.copy())
    assert same.digest(a) != same.digest(b)
    assert same.digest(np.array([0.0])) != same.digest(np.array([-0.0]))
    assert same.digest(a) != same.digest(a.astype(np.float32))  # dtype counts
    assert same.digest(a.reshape(3, 1)) != same.digest(a)  # shape counts
    assert same.digest({"x": 0.1}) != same.digest({"x": 0.1 + 2**-56})
    assert same.digest({"x": 1, "y": 2}) == same.digest({"y": 2, "x": 1})


def test_wall_clock_figures_are_left_out_and_nothing_else():
    run = {
        "rmse_m": 0.05,
        "loop_s": 12.3,
        "seconds": 9.0,
        "nested": {"timing": {"step_us": 3.0}, "seconds": [1, 2, 3], "compile_seconds": 40.0},
    }
    kept = same.without_clock(run)
    assert kept == {"rmse_m": 0.05, "nested": {"seconds": [1, 2, 3]}}
    assert same.digest(same.without_clock(dict(run, loop_s=99.0))) == same.digest(kept)
    assert same.digest(same.without_clock(dict(run, rmse_m=0.06))) != same.digest(kept)


def test_the_report_names_what_differs():
    base = {
        "battery/holdout/kidnap/1000": "a",
        "battery/holdout/kidnap/1001": "b",
        "walk/constant/0": "c",
        "replay/0": "d",
    }
    current = dict(base, **{"battery/holdout/kidnap/1001": "x", "replay/0": "d"})
    del current["walk/constant/0"]
    rows = same.compare(base, current)
    assert [r["case"] for r in rows if not r["same"]] == ["battery/holdout/kidnap/1001", "walk/constant/0"]
    text = "\n".join(same.summary_lines(rows))
    assert "battery/holdout/kidnap" in text and "1/2 runs same" in text and "seeds 1001" in text
    assert "walk/constant/0" in text and "DIFFERENT" in text
    assert all(r["same"] for r in same.compare(base, dict(base)))


@pytest.mark.parametrize("argv", [["--sections", "everything"], ["--seeds", "0"], ["--jobs", "0"]])
def test_bad_options_are_refused(argv):
    with pytest.raises(SystemExit) as raised:
        same.main(argv)
    assert raised.value.code == 2


def test_a_saved_result_is_shown_again(tmp_path, capsys):
    rows = same.compare({"replay/0": "a", "walk/constant/0": "b"}, {"replay/0": "a", "walk/constant/0": "c"})
    result = {"base": "REV", "current": "working tree", "cases": 2, "different": ["walk/constant/0"], "rows": rows}
    saved = tmp_path / "same.json"
    saved.write_text(__import__("json").dumps(result))
    assert same.main(["--show", str(saved)]) == 0
    out = capsys.readouterr().out
    assert out.startswith("REV against the working tree: 1/2 cases bit for bit the same")
    assert "walk/constant/0" in out and "DIFFERENT" in out
