"""The size of a Rerun recording, measured: bytes per minute of recorded time and chunk counts, from a command.

    python -m benchmarks.recording_stats [--particles N] [--seed S] [--every K] [--rrd PATH | --file PATH]
                                         [--json] [--save PATH]

Run from the repository root. It records the walk demo (`demos.walk.run_walk`: 60 s at 100 Hz, the particles
every K-th step) to PATH (a temporary file unless `--rrd` is given), or with `--file` measures an existing
.rrd instead, and reports:

  size_bytes, duration_s, bytes_per_minute   the file's size and the span of its `time` timeline
  chunks            the chunks in the file, read back with the SDK (`rerun.chunk.RrdReader`): in the recording
                    (temporal and static) and in the blueprint, and the recording's chunks per entity
  rrd_stats         what `rerun rrd stats` says (when the `rerun` command is found next to this Python or on
                    PATH): its chunk count, the optimization check's lower bound and effective count, and
                    whether it warns that the file may be unoptimized
  record_seconds    the wall time of the demo run with its recording, closing included; filter_seconds: the
                    demo's step loop alone, the recorder's calls included (both not with `--file`; after a 2 s
                    walk without recording, which compiles the kernels or loads them from numba's cache)
"""

from __future__ import annotations

import argparse
import json
import re
import shutil
import subprocess
import sys
import tempfile
import time
from collections import Counter
from pathlib import Path

NS = 1e-9


def rerun_command() -> str | None:
    """The `rerun` command installed with the SDK (next to this interpreter), else the one on PATH, else None."""
    local = Path(sys.executable).parent / "rerun"
    return str(local) if local.exists() else shutil.which("rerun")


def chunk_counts(path: Path) -> dict:
    """Chunks of the file's recording (temporal, static, per entity) and blueprint, and the recording's time
    span [s] (the `time` timeline, None without one)."""
    import rerun.chunk as rrc

    reader = rrc.RrdReader(str(path))
    per_entity: Counter = Counter()
    temporal = static = 0
    low, high = None, None
    for chunk in reader.stream():
        per_entity[chunk.entity_path] += 1
        if chunk.is_static:
            static += 1
            continue
        temporal += 1
        if "time" in chunk.timeline_names:
            batch = chunk.to_record_batch()
            values = batch.column(batch.schema.names.index("time")).cast("int64").to_numpy()
            if values.size:
                low = int(values.min()) if low is None else min(low, int(values.min()))
                high = int(values.max()) if high is None else max(high, int(values.max()))
    blueprint = sum(1 for entry in reader.blueprints() for _ in reader.stream(store=entry))
    return {
        "recording": temporal + static,
        "temporal": temporal,
        "static": static,
        "blueprint": blueprint,
        "total": temporal + static + blueprint,
        "per_entity": dict(sorted(per_entity.items())),
        "_span_s": None if low is None else (high - low) * NS,
    }


def rrd_stats(path: Path) -> dict | None:
    """The figures of `rerun rrd stats PATH` (None when the command is not found)."""
    command = rerun_command()
    if command is None:
        return None
    done = subprocess.run([command, "rrd", "stats", str(path)], capture_output=True, text=True, check=True)
    text = done.stdout

    def number(pattern: str) -> int | None:
        found = re.search(pattern, text)
        return None if found is None else int(found.group(1).replace(" ", "").replace("\u202f", ""))

    return {
        "num_chunks": number(r"num_chunks = ([\d \u202f]+)"),
        "lower_bound_chunks": number(r"theoretical lower bound:\s*([\d \u202f]+) chunks"),
        "effective_chunks": number(r"effective:\s*([\d \u202f]+) chunks"),
        "unoptimized_warning": "may be unoptimized" in text,
    }


def measure(path: Path, record_seconds: float | None = None, run: dict | None = None) -> dict:
    """The report for the .rrd file at `path`."""
    chunks = chunk_counts(path)
    span = chunks.pop("_span_s")
    size = path.stat().st_size
    per_minute = None if not span else size * 60.0 / span
    return {
        "file": str(path),
        "revision": revision(),
        "run": run,
        "size_bytes": size,
        "duration_s": span,
        "bytes_per_minute": per_minute,
        "mib_per_minute": None if per_minute is None else per_minute / 2**20,
        "chunks": chunks,
        "rrd_stats": rrd_stats(path),
        "record_seconds": record_seconds,
    }


def revision() -> str | None:
    """The working tree's commit (short), None outside git."""
    try:
        return subprocess.run(
            ["git", "rev-parse", "--short", "HEAD"], capture_output=True, text=True, check=True
        ).stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        return None


def record_walk(path: Path, particles: int, seed: int, every: int) -> tuple[float, dict]:
    """Record the walk demo to `path`; the wall time (closing included) and the run's settings."""
    from dataclasses import replace

    from demos.walk import run_walk
    from demos.walk_sim import WalkScenario

    run_walk(particles=particles, seed=seed, scenario=replace(WalkScenario(), duration=2.0))  # compiles, unrecorded
    started = time.perf_counter()
    result = run_walk(particles=particles, seed=seed, rrd=str(path), record_every=every)
    elapsed = time.perf_counter() - started
    return elapsed, {
        "demo": "walk",
        "particles": particles,
        "seed": seed,
        "particles_every": every,
        "steps": result["steps"],
        "filter_seconds": result["filter_seconds"],
    }


def table(report: dict) -> str:
    """The report as a few lines of text."""
    chunks, stats = report["chunks"], report["rrd_stats"]
    lines = [
        f"file              {report['file'] or '(a temporary file)'}",
        f"size              {report['size_bytes'] / 2**20:.2f} MiB over {report['duration_s']:.1f} s"
        f" = {report['mib_per_minute']:.2f} MiB per minute",
        f"chunks (SDK)      {chunks['total']} ({chunks['temporal']} temporal, {chunks['static']} static,"
        f" {chunks['blueprint']} blueprint)",
    ]
    if stats is not None:
        lines.append(
            f"rerun rrd stats   {stats['num_chunks']} chunks; lower bound {stats['lower_bound_chunks']},"
            f" effective {stats['effective_chunks']}"
            + ("; warns: may be unoptimized" if stats["unoptimized_warning"] else "")
        )
    if report["record_seconds"] is not None:
        lines.append(f"recorded in       {report['record_seconds']:.2f} s")
    return "\n".join(lines)


def parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="python -m benchmarks.recording_stats",
        description="Size per minute and chunk count of the walk demo's recording.",
    )
    p.add_argument("--particles", type=int, default=500, help="particles (default 500, the demo's)")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--every", type=int, default=5, help="log the particles every K-th step (default 5)")
    where = p.add_mutually_exclusive_group()
    where.add_argument("--rrd", metavar="PATH", help="write the recording here (default: a temporary file)")
    where.add_argument("--file", metavar="PATH", help="measure this .rrd instead of recording one")
    p.add_argument("--json", action="store_true", help="print JSON instead of the table")
    p.add_argument("--save", metavar="PATH", help="write the JSON report to PATH (parent directories created)")
    return p


def main(argv: list[str] | None = None) -> int:
    args = parser().parse_args(argv)
    with tempfile.TemporaryDirectory() as scratch:
        if args.file:
            path = Path(args.file)
            if not path.is_file():
                print(f"recording_stats: {path} is not a file", file=sys.stderr)
                return 1
            report = measure(path)
        else:
            path = Path(args.rrd) if args.rrd else Path(scratch) / "walk.rrd"
            seconds, run = record_walk(path, args.particles, args.seed, args.every)
            report = measure(path, seconds, run)
            if not args.rrd:
                report["file"] = None
    text = json.dumps(report, indent=2)
    if args.save:
        Path(args.save).parent.mkdir(parents=True, exist_ok=True)
        Path(args.save).write_text(text + "\n")
    print(text if args.json else table(report))
    return 0


if __name__ == "__main__":
    sys.exit(main())
