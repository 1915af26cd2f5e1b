"""The docs' screenshots of a recording, taken by the Rerun viewer itself.

    python -m benchmarks.screenshots [--out docs/images] [--size 1600x900] [--xvfb | --no-xvfb]

Run from the repository root. It records the walk demo (`demos.walk.run_walk`, seed 0, 500 particles) twice, the
whole minute and the run stopped 0.1 s after the kidnapping, writes a blueprint per picture (the
default one, opened at the end of the recording, `--screenshot-to`'s moment; for the close-up, the field view
bounded around the robot) and has the viewer (`rerun FILE.rrd VIEW.rbl --screenshot-to PNG --window-size`)
write:

  recording_walk.png          the whole run: the field at the end, the plots with the event marks, the log
  recording_walk_kidnap.png   0.1 s after the kidnapping: the belief where the robot was, the rays that disagree
  recording_walk_closeup.png  the end of the run, 1.5 m around the robot: headings, ellipses, rays

Without a display (or with `--xvfb`) it starts Xvfb on a free display for the viewer and stops it afterwards;
with Mesa's software Vulkan driver (lavapipe: Debian's mesa-vulkan-drivers) the viewer renders on the CPU,
about half a minute per picture. Needs the `rerun` command installed with the SDK and, for `--xvfb`, Xvfb.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from dataclasses import replace
from pathlib import Path

LAVAPIPE = Path("/usr/share/vulkan/icd.d/lvp_icd.x86_64.json")
APPLICATION_ID = "robocup-mcl"
MAX_BYTES = 1_000_000
KIDNAP_CLIP = 0.1  # s the kidnapping picture's run goes on after the kidnapping


def free_display() -> int:
    """A display number with no X server's lock file."""
    for number in range(99, 200):
        if not Path(f"/tmp/.X{number}-lock").exists() and not Path(f"/tmp/.X11-unix/X{number}").exists():
            return number
    raise RuntimeError("no free X display number in 99..199")


class Xvfb:
    """A virtual X server for the viewer's window, larger than it so that the pointer (at the screen's centre)
    stays off the window and no hover readout shows."""

    def __init__(self, width: int, height: int) -> None:
        self.display = f":{free_display()}"
        self.process = subprocess.Popen(
            ["Xvfb", self.display, "-screen", "0", f"{2 * width}x{2 * height}x24", "-nolisten", "tcp"],
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
        )
        for _ in range(50):
            if Path(f"/tmp/.X11-unix/X{self.display[1:]}").exists():
                return
            if self.process.poll() is not None:
                raise RuntimeError(f"Xvfb {self.display} exited with {self.process.returncode}")
            time.sleep(0.1)
        raise RuntimeError(f"Xvfb {self.display} did not start")

    def stop(self) -> None:
        self.process.terminate()
        self.process.wait(timeout=10)


def rerun_command() -> str:
    from benchmarks.recording_stats import rerun_command as find

    command = find()
    if command is None:
        raise RuntimeError("the `rerun` command (installed with rerun-sdk) was not found")
    return command


def screenshot(rrd: Path, blueprint, png: Path, size: str, display: str | None) -> None:
    """Open `rrd` with `blueprint` in the viewer and have it write `png`."""
    env = dict(os.environ)
    if display is not None:
        env["DISPLAY"] = display
    if LAVAPIPE.exists() and "VK_ICD_FILENAMES" not in env:
        env["VK_ICD_FILENAMES"] = str(LAVAPIPE)
    env.setdefault("XDG_RUNTIME_DIR", tempfile.gettempdir())
    view = png.with_suffix(".rbl")
    try:
        blueprint.save(APPLICATION_ID, str(view))
        done = subprocess.run(
            [
                rerun_command(),
                str(rrd),
                str(view),
                "--screenshot-to",
                str(png),
                "--window-size",
                size,
                "--renderer",
                "vulkan",
                "--port",
                "auto",
                "--hide-welcome-screen",
            ],
            env=env,
            capture_output=True,
            text=True,
            timeout=600,
        )
    finally:
        view.unlink(missing_ok=True)
    if done.returncode != 0 or not png.exists():
        raise RuntimeError(f"the viewer did not write {png} (exit {done.returncode}):\n{done.stderr[-3000:]}")


def make(out: Path, size: str, use_xvfb: bool) -> list[Path]:
    """Record the clips and take the three pictures into `out`; returns their paths."""
    import rerun.blueprint as rrb

    from demos.walk import run_walk
    from demos.walk_sim import WalkScenario
    from mcl.tools.recording import default_blueprint

    out.mkdir(parents=True, exist_ok=True)
    width, height = (int(v) for v in size.split("x"))
    at_end = rrb.TimePanel(timeline="time", play_state="following", state="collapsed")
    server = Xvfb(width, height) if use_xvfb else None
    written = []
    try:
        with tempfile.TemporaryDirectory() as scratch:
            whole, kidnap = Path(scratch) / "walk.rrd", Path(scratch) / "kidnap.rrd"
            result = run_walk(rrd=str(whole), series=True)
            scenario = WalkScenario()
            run_walk(rrd=str(kidnap), scenario=replace(scenario, duration=scenario.kidnap_time + KIDNAP_CLIP))
            x, y = result["series"]["truth"][-1, :2]
            display = server.display if server is not None else None
            for name, rrd, blueprint in (
                ("recording_walk.png", whole, default_blueprint(time_panel=at_end)),
                ("recording_walk_kidnap.png", kidnap, default_blueprint(time_panel=at_end)),
                (
                    "recording_walk_closeup.png",
                    whole,
                    default_blueprint(field_bounds=((x - 1.5, x + 1.5), (y - 1.0, y + 1.0)), time_panel=at_end),
                ),
            ):
                png = out / name
                screenshot(rrd, blueprint, png, size, display)
                if png.stat().st_size > MAX_BYTES:
                    print(f"screenshots: {png} is {png.stat().st_size} bytes (over {MAX_BYTES})", file=sys.stderr)
                written.append(png)
    finally:
        if server is not None:
            server.stop()
    return written


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(
        prog="python -m benchmarks.screenshots",
        description="The docs' screenshots of the walk demo's recording, by the viewer.",
    )
    p.add_argument("--out", default="docs/images", help="directory for the PNGs (default docs/images)")
    p.add_argument("--size", default="1600x900", help="the viewer's window in logical points (default 1600x900)")
    xvfb = p.add_mutually_exclusive_group()
    xvfb.add_argument(
        "--xvfb",
        dest="xvfb",
        action="store_true",
        default=None,
        help="run the viewer on a virtual X server (default: when DISPLAY is not set)",
    )
    xvfb.add_argument("--no-xvfb", dest="xvfb", action="store_false", help="use the current DISPLAY")
    args = p.parse_args(argv)
    use_xvfb = not os.environ.get("DISPLAY") if args.xvfb is None else args.xvfb
    try:
        for png in make(Path(args.out), args.size, use_xvfb):
            print(f"{png} ({png.stat().st_size} bytes)")
    except (RuntimeError, OSError, subprocess.TimeoutExpired) as error:
        print(f"screenshots: {error}", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
