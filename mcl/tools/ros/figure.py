"""`robocup-mcl node figure PUBLISHED.json`: a picture of what the live node published, from a real run.

    robocup-mcl node bench game.mcap --field kidsize --seconds 60 --published results/ros_published.json
    robocup-mcl node figure results/ros_published.json --out docs/images/ros_node.png --at 40

The JSON is what `robocup-mcl node bench --published` recorded with its listener over DDS (`PoseListener.published`):
the field's visualization_msgs/MarkerArray, every PoseWithCovarianceStamped and the latest particle PoseArrays.
The figure draws exactly those: the markers (line lists, line strips, cylinders seen from above), the particles
of the particle message nearest `--at` seconds into the run (dots with short heading ticks), the published poses
of the `--trail` seconds up to it (a line) and the pose at that moment (an arrow). Nothing is recomputed.
Needs matplotlib (`pip install -e '.[bench]'`); it runs without ROS.
"""

from __future__ import annotations

import json
import math
import sys
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    import argparse

PROG = "robocup-mcl node figure"
# visualization_msgs/Marker types the node publishes
CYLINDER, LINE_STRIP, LINE_LIST = 3, 4, 5


def nearest(items: list, stamp: int, key) -> Any:
    """The item of `items` whose `key(item)` is nearest `stamp`."""
    return min(items, key=lambda item: abs(key(item) - stamp))


def draw(published: dict, out: str, at: float | None = None, trail: float = 10.0, dpi: int = 110) -> dict:
    """Draw `published` (see the module docstring) to the image `out`; returns what was drawn (the moment's
    stamp, the poses in the trail, the particles)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.patches import Circle

    poses = published["poses"]
    snapshots = published["particles"]
    if not poses or not snapshots or not published["field_markers"]:
        raise ValueError("the file holds no poses, no particle message or no field markers")
    origin = poses[0][0]
    moment = snapshots[-1]["stamp_ns"] if at is None else origin + round(at * 1e9)
    snapshot = nearest(snapshots, moment, lambda s: s["stamp_ns"])
    moment = snapshot["stamp_ns"]
    pose = nearest(poses, moment, lambda p: p[0])
    shown = [p for p in poses if moment - trail * 1e9 <= p[0] <= moment]

    fig, ax = plt.subplots(figsize=(9.6, 6.6))
    ax.set_facecolor((0.16, 0.45, 0.2))
    xs, ys = [], []
    for marker in published["field_markers"]:
        points = marker["points"]
        if marker["type"] == LINE_LIST:
            for (x0, y0), (x1, y1) in zip(points[0::2], points[1::2]):
                ax.plot([x0, x1], [y0, y1], color="white", lw=1.6, solid_capstyle="butt")
            xs += [p[0] for p in points]
            ys += [p[1] for p in points]
        elif marker["type"] == LINE_STRIP:
            ax.plot([p[0] for p in points], [p[1] for p in points], color="white", lw=1.6)
        elif marker["type"] == CYLINDER:
            colour = "yellow" if marker["ns"] == "goalposts" else "white"
            radius = max(0.5 * marker["scale_x"], 0.04)
            ax.add_patch(Circle(marker["position"], radius, color=colour, zorder=3))
    particles = snapshot["poses"]
    px, py = [p[0] for p in particles], [p[1] for p in particles]
    ax.scatter(px, py, s=5, color=(0.55, 0.8, 1.0), zorder=4, label=f"particles ({len(particles)})")
    tick = 0.15
    for x, y, theta in particles[:: max(1, len(particles) // 150)]:
        ax.plot(
            [x, x + tick * math.cos(theta)], [y, y + tick * math.sin(theta)], color=(0.55, 0.8, 1.0), lw=0.6, zorder=4
        )
    ax.plot(
        [p[1] for p in shown],
        [p[2] for p in shown],
        color=(1.0, 0.35, 0.3),
        lw=1.4,
        zorder=5,
        label=f"published poses, last {trail:g} s",
    )
    _, x, y, theta = pose
    ax.annotate(
        "",
        xy=(x + 0.5 * math.cos(theta), y + 0.5 * math.sin(theta)),
        xytext=(x, y),
        arrowprops={"arrowstyle": "-|>", "color": (1.0, 0.2, 0.2), "lw": 2.2},
        zorder=6,
    )
    ax.plot([x], [y], "o", color=(1.0, 0.2, 0.2), ms=5, zorder=6, label="the pose at that moment")
    margin = 0.8
    ax.set_xlim(min(xs) - margin, max(xs) + margin)
    ax.set_ylim(min(ys) - margin, max(ys) + margin)
    ax.set_aspect("equal")
    ax.set_xlabel("x [m] (map frame)")
    ax.set_ylabel("y [m]")
    seconds = (moment - origin) / 1e9
    ax.set_title(
        f"robocup-mcl node over DDS: /robocup_mcl/field, /pose and /particles as received, {seconds:.1f} s into "
        f"{published.get('log', 'the log')}",
        fontsize=9,
    )
    ax.legend(loc="upper right", fontsize=8, framealpha=0.85)
    fig.tight_layout()
    fig.savefig(out, dpi=dpi)
    plt.close(fig)
    return {"stamp_ns": moment, "seconds": seconds, "trail_poses": len(shown), "particles": len(particles)}


def build_parser(prog: str = PROG) -> argparse.ArgumentParser:
    """The command's argument parser, named `prog` in its usage line."""
    import argparse

    from mcl.tools.cli_checks import NO_PROGRESS_HELP

    parser = argparse.ArgumentParser(
        prog=prog,
        description="Draw what the live node published in a real run (the JSON of robocup-mcl node bench "
        "--published): the field's markers, the particles and the poses, as a PNG.",
    )
    parser.add_argument("published", help="the JSON written by robocup-mcl node bench --published")
    parser.add_argument("--out", required=True, help="the image to write (.png)")
    parser.add_argument(
        "--at", type=float, default=None, help="seconds into the run (default: the last particle message)"
    )
    parser.add_argument("--trail", type=float, default=10.0, help="seconds of poses drawn up to it (default 10)")
    parser.add_argument("--no-progress", action="store_true", help=NO_PROGRESS_HELP + "; this command shows none")
    return parser


def main(argv: list[str] | None = None, prog: str = PROG) -> int:
    """`robocup-mcl node figure PUBLISHED.json --out PNG` (see `--help`); returns the exit status."""
    from mcl.tools.cli_checks import CommandError, check_output_file

    args = build_parser(prog).parse_args(sys.argv[1:] if argv is None else argv)
    if not args.trail > 0:
        raise CommandError("--trail must be > 0")
    check_output_file(args.out, "--out")
    try:
        with open(args.published, encoding="utf-8") as stream:
            published = json.load(stream)
    except (OSError, ValueError) as error:
        raise CommandError(f"{args.published}: {error}") from None
    try:
        import matplotlib  # noqa: F401
    except ImportError:
        raise CommandError("matplotlib is not installed here: `pip install -e '.[bench]'` installs it") from None
    try:
        drawn = draw(published, args.out, args.at, args.trail)
    except (KeyError, TypeError, ValueError) as error:
        raise CommandError(f"{args.published}: not what node bench --published writes ({error})") from None
    print(
        f"{args.out}: {drawn['seconds']:.1f} s into the run, {drawn['particles']} particles, "
        f"{drawn['trail_poses']} poses"
    )
    return 0


if __name__ == "__main__":
    from mcl.tools.cli_checks import run_main

    raise SystemExit(run_main(main, "python -m mcl.tools.ros.figure"))
