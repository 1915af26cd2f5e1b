"""`robocup-mcl demo venue`: logs from a new venue, whose odometry and detection noise differ from the
library's defaults, for trying `robocup-mcl tune` without ground truth.

    robocup-mcl demo venue --out venue/ [--logs 12] [--first 0] [--duration 60] [--scale 1.2] [--noise 1.2]
                           [--json] [--save PATH]

Each log is a run of the evaluation battery's simulator (`demos.battery_sim`, family "tracking": walking on the
SPL, kid-size or adult-size field with its own gait, drift, camera, latency, false detections and detection
rate, all drawn per run from the battery's ranges), with these drawn parameters replaced:
- the odometry reports `scale` times the motion (all three axes; the default model assumes 1);
- the detections' noise is `noise` times the library's default landmark model (`sensing.LandmarkSensorModel`:
  range σ = a + c·r² with its a and c, bearing σ its bearing_sigma), read from the library at run time.
So with the defaults (1.2 and 1.2) the venue is 20 % off the defaults in both. The logs are written with
`mcl.tools.logs.write_log` (columnar .npz) and carry the truth, which `robocup-mcl tune --objective evidence` does
not read; the report uses it to say how far off each profile is. Log i (venue-00i.npz) is the battery's run of
seed first + 3·i: with `--first` a multiple of 3 every log is on the SPL field (a venue has one field).
"""

from __future__ import annotations

import argparse
import math
import os

PROG = "robocup-mcl demo venue"
STRIDE = 3  # the battery's field cycles with the seed (FIELDS[seed % 3]): one field per venue


def venue_overrides(scale: float, noise: float) -> dict:
    """The battery simulator's parameters a venue replaces (see the module docstring)."""
    from mcl.profile import default_values

    defaults = default_values()
    return {
        "odometry_scale": [scale] * 3,
        "range_law": "quadratic",
        "range_a": noise * defaults["sensor.range_noise_floor"],
        "range_growth": noise * defaults["sensor.range_noise_growth"],
        "bearing_sigma": noise * defaults["sensor.bearing_sigma"],
    }


def write_venue(
    out: str,
    logs: int = 12,
    first: int = 0,
    duration: float = 60.0,
    scale: float = 1.2,
    noise: float = 1.2,
    progress: bool = False,
) -> dict:
    """Write the venue's logs to the folder `out`; returns {"files", "overrides", "fields"}."""
    from mcl.tools.cli_checks import progress_bar
    from mcl.tools.logs import write_log

    from .battery_sim import as_robot_log, simulate

    os.makedirs(out, exist_ok=True)
    overrides = venue_overrides(scale, noise)
    files, fields = [], []
    bar = progress_bar(enabled=progress, total=logs, desc="venue", unit="log")
    for i in range(logs):
        seed = first + STRIDE * i
        run = simulate("tracking", seed, duration, overrides)
        path = os.path.join(out, f"venue-{i:03d}.npz")
        write_log(as_robot_log(run), path)
        files.append(path)
        fields.append(run.field.name)
        bar.update(1)
    bar.close()
    return {
        "files": files,
        "fields": fields,
        "overrides": overrides,
        "scale": scale,
        "noise": noise,
        "duration_s": duration,
        "seeds": [first + STRIDE * i for i in range(logs)],
    }


def build_parser(prog: str = PROG) -> argparse.ArgumentParser:
    """The command's argument parser, named `prog` in its usage line."""
    from mcl.tools.cli_checks import add_progress_option, add_save_option, description, positive_int

    parser = argparse.ArgumentParser(prog=prog, description=description(__doc__))
    parser.add_argument("--out", required=True, metavar="DIR", help="the folder to write the logs to")
    parser.add_argument("--logs", type=positive_int, default=12, help="how many logs (default 12)")
    parser.add_argument("--first", type=int, default=0, help="the first log's seed (default 0)")
    parser.add_argument("--duration", type=float, default=60.0, help="seconds per log (default 60, at least 10)")
    parser.add_argument("--scale", type=float, default=1.2, help="odometry scale of the venue (default 1.2)")
    parser.add_argument(
        "--noise", type=float, default=1.2, help="detection noise as a multiple of the default model's (default 1.2)"
    )
    parser.add_argument("--json", action="store_true", help="print what was written as JSON")
    add_save_option(parser)
    add_progress_option(parser)
    return parser


def main(argv: list[str] | None = None, prog: str = PROG) -> int:
    """The command line (see the module docstring)."""
    from mcl.tools.cli_checks import (
        check_duration,
        check_output_directory,
        check_output_file,
        progress_wanted,
        save_and_print,
    )

    parser = build_parser(prog)
    args = parser.parse_args(argv)
    if args.first < 0:
        parser.error(f"--first {args.first} must be >= 0")
    check_duration(parser, args.duration, 10.0)
    for name in ("scale", "noise"):
        value = getattr(args, name)
        if not (math.isfinite(value) and 0.1 <= value <= 10.0):
            parser.error(f"--{name} {value} must lie in [0.1, 10]")
    check_output_directory(args.out, "--out")
    check_output_file(args.save, "--save")
    result = write_venue(args.out, args.logs, args.first, args.duration, args.scale, args.noise, progress_wanted(args))

    def printer(r: dict) -> None:
        print(
            f"{len(r['files'])} logs of {r['duration_s']:g} s on the {', '.join(sorted(set(r['fields'])))} field "
            f"written to {args.out} (odometry ×{r['scale']:g}, detection noise ×{r['noise']:g} the defaults): "
            f"{', '.join(os.path.basename(f) for f in r['files'])}"
        )

    save_and_print(result, args.save, args.json, printer)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
