"""The targets of `robocup-mcl bench`, its text report and its scaling plot.

    from benchmarks.report import evaluate_targets, format_report, plot
    result["targets"] = evaluate_targets(result)   # each: target, value, met (True / False / None: not measured)
    print(format_report(result))
    plot(result, "bench.png")                      # needs matplotlib (pip install -e '.[bench]')

Every target is printed with its measured value and "met" or "NOT MET"; one that could not be measured in
this run says why ("not measured: ..." or "not available: ...").
"""

from __future__ import annotations

from .step import PHASES

ADAPTIVE_PHASES = ("predict_adaptive", "predict_adaptive_quiet")  # during collisions, walking freely


def adaptive_ratios(result: dict) -> list[tuple[int, float]]:
    """(N, adaptive predict / velocity-linear predict) for each row that timed both; of the adaptive phases
    (frequent collisions, quiet walking) the slower."""
    ratios = []
    for row in result.get("rows", []):
        linear = row["phases"].get("predict_velocity_linear", {}).get("numba_s")
        adaptive = [row["phases"].get(name, {}).get("numba_s") for name in ADAPTIVE_PHASES]
        adaptive = [a for a in adaptive if a]
        if adaptive and linear:
            ratios.append((row["n"], max(adaptive) / linear))
    return ratios


def _rows_at_least(result: dict, n_min: int) -> list[dict]:
    return [row for row in result.get("rows", []) if row["n"] >= n_min]


def _row(result: dict, n: int) -> dict | None:
    return next((row for row in result.get("rows", []) if row["n"] == n), None)


def _target(key: str, text: str, value, unit: str, met, note: str = "") -> dict:
    return {"id": key, "target": text, "value": value, "unit": unit, "met": met, "note": note}


def _at_most(key, text, value, limit, unit, missing_note):
    if value is None:
        return _target(key, text, None, unit, None, missing_note)
    return _target(key, text, value, unit, bool(value <= limit))


def _at_least(key, text, value, limit, unit, missing_note):
    if value is None:
        return _target(key, text, None, unit, None, missing_note)
    return _target(key, text, value, unit, bool(value >= limit))


def _section(result: dict, name: str) -> dict | None:
    section = result.get(name)
    if not isinstance(section, dict) or "error" in section:
        return None
    return section


def evaluate_targets(result: dict) -> list[dict]:
    """The issue's targets against this run's figures."""
    targets = []
    big = _rows_at_least(result, 10_000)
    worst_ns = max((row["ns_per_particle"] for row in big), default=None)

    def worst(key):
        values = [row[key]["numba_ns_per_particle"] for row in big if row.get(key)]
        return max(values) if values and len(values) == len(big) else None

    targets.append(
        _at_most(
            "full_step_ns_per_particle",
            "full step, one thread, N >= 10 000: <= 80 ns/particle (worst N)",
            worst_ns,
            80.0,
            "ns/particle",
            "not measured: no N >= 10 000",
        )
    )
    targets.append(
        _at_most(
            "issue_step_ns_per_particle",
            "the issue's step shape (no roughening, no estimate), N >= 10 000: <= 80 ns/particle (worst N)",
            worst("issue_step"),
            80.0,
            "ns/particle",
            "not measured",
        )
    )
    targets.append(
        _at_most(
            "full_step_ns_per_particle_aim",
            "full step with fast=True (fast-math), N >= 10 000: aim <= 40 ns/particle (worst N)",
            worst("full_step_fast"),
            40.0,
            "ns/particle",
            "not measured: no fast option or no N >= 10 000",
        )
    )
    targets.append(
        _at_most(
            "issue_step_ns_per_particle_aim",
            "the issue's step shape with fast=True, N >= 10 000: aim <= 40 ns/particle (worst N)",
            worst("issue_step_fast"),
            40.0,
            "ns/particle",
            "not measured: no fast option or no N >= 10 000",
        )
    )
    for n, key, limit, unit, scale in (
        (1000, "full_step_1000", 0.1, "ms", 1e3),
        (100, "full_step_100", 15.0, "µs", 1e6),
    ):
        row = _row(result, n)
        size = f"{n:,}".replace(",", " ")
        target = _at_most(
            key,
            f"full step, N = {size}: <= {limit:g} {unit}",
            None if row is None else scale * row["full_step"]["numba_s"],
            limit,
            unit,
            f"not measured: N = {size} not among the sizes",
        )
        warm = None if row is None else row.get("full_step_back_to_back")
        if warm and target["met"] is not None:
            target["note"] = f"back to back {scale * warm['numba_s']:.3g} {unit}"
        targets.append(target)
        # The issue states these two for its own step shape, one dispatch into compiled code per step.
        shaped = None if row is None else row.get("issue_step")
        targets.append(
            _at_most(
                f"issue_step_{n}",
                f"the issue's step shape (one dispatch), N = {size}: <= {limit:g} {unit}",
                None if shaped is None else scale * shaped["numba_s"],
                limit,
                unit,
                f"not measured: N = {size} not among the sizes",
            )
        )
    targets.append(
        _at_least(
            "speedup_10000",
            "full step >= 5x plain numpy at N >= 10 000 (worst N)",
            min((row["speedup"] for row in big), default=None),
            5.0,
            "x",
            "not measured: no N >= 10 000",
        )
    )
    row = _row(result, 100)
    targets.append(
        _at_least(
            "speedup_100",
            "full step >= 20x plain numpy at N = 100",
            None if row is None else row["speedup"],
            20.0,
            "x",
            "not measured: N = 100 not among the sizes",
        )
    )

    threads = _section(result, "threads")
    if threads is None:
        targets.append(
            _target(
                "two_threads",
                "two threads >= 1.7x one at N >= 10^5",
                None,
                "x",
                None,
                "not measured: threads skipped or failed",
            )
        )
    elif not threads.get("available"):
        targets.append(
            _target(
                "two_threads",
                "two threads >= 1.7x one at N >= 10^5",
                None,
                "x",
                None,
                threads.get("note") or "not available",
            )
        )
    else:
        two = _at_least(
            "two_threads",
            "two threads >= 1.7x one at N >= 10^5 (worst N)",
            min((r["speedup"] for r in threads["rows"]), default=None),
            1.7,
            "x",
            threads.get("note") or "not measured",
        )
        if threads["rows"] and threads.get("note"):
            two["note"] = threads["note"]
        targets.append(two)

    peers = _section(result, "resampling")
    at_million = None if peers is None else next((r for r in peers["rows"] if r["n"] == 1_000_000), None)
    targets.append(
        _at_most(
            "resampling_1e6",
            "systematic resampling <= 3 ns/particle at N = 10^6",
            None if at_million is None else at_million["best_ours_ns_per_particle"],
            3.0,
            "ns/particle",
            "not measured: N = 10^6 not among the sizes (or peers skipped)",
        )
    )

    memory = _section(result, "memory")
    if memory is None:
        targets.append(
            _target(
                "steady_state_allocation",
                "steady-state step: no allocation growing with N",
                None,
                "",
                None,
                "not measured: memory skipped or failed",
            )
        )
    else:
        rows = memory["rows"]
        value = rows[-1]["step_peak_bytes_per_particle"]
        kernel_growth = memory.get("kernel_allocations_grow_with_n", False)
        met = not memory["grows_with_n"] and not memory["retains_memory"] and not kernel_growth
        note = (
            f"scratch per step {rows[0]['step_peak_bytes']:,} B at N = {rows[0]['n']:,}, "
            f"{rows[-1]['step_peak_bytes']:,} B at N = {rows[-1]['n']:,} ({memory['step_peak_ratio']:.1f}x)"
        )
        counts = [row["numba_allocations_per_step"] for row in rows]
        if None not in counts:
            note += (
                f"; numba allocations per step {counts[0]:.0f} -> {counts[-1]:.0f}"
                f"{' (grows with N)' if kernel_growth else ''}"
            )
        targets.append(
            _target(
                "steady_state_allocation",
                "steady-state step: no allocation growing with N",
                value,
                "B/particle per step",
                met,
                note,
            )
        )

    walk = _section(result, "demo_walk")
    walk_target = _at_most(
        "demo_walk_cached",
        "cached start-up: demo walk, 10 steps, <= 3 s",
        None if walk is None else walk["wall_s"],
        3.0,
        "s",
        "not measured: start-up skipped or failed",
    )
    if walk is not None and walk.get("note"):
        walk_target["note"] = walk["note"]
    targets.append(walk_target)

    ratios = adaptive_ratios(result)
    judged = [r for n, r in ratios if n >= 10_000] or [r for _, r in ratios]
    targets.append(
        _at_most(
            "adaptive_vs_velocity_linear",
            "adaptive predict <= 1.5x velocity-linear (worst N >= 10 000, else worst N)",
            max(judged, default=None),
            1.5,
            "x",
            "not measured",
        )
    )

    models = _section(result, "models")
    lwpr = None if models is None else models.get("lwpr")
    ekf = None if models is None else models.get("ekf", {}).get("default")
    targets.append(
        _at_most(
            "lwpr_update",
            "LWPR update (2 inputs) <= 10 µs",
            None if not lwpr else lwpr["update_us"],
            10.0,
            "µs",
            "not measured",
        )
    )
    targets.append(
        _at_most(
            "lwpr_predict",
            "LWPR predict (2 inputs) <= 5 µs",
            None if not lwpr else lwpr["predict_us"],
            5.0,
            "µs",
            "not measured",
        )
    )
    targets.append(
        _at_most(
            "ekf_predict",
            "velocity EKF prediction <= 10 µs",
            None if not ekf else ekf["predict_us"],
            10.0,
            "µs",
            "not measured",
        )
    )
    targets.append(
        _at_most(
            "ekf_correct",
            "velocity EKF correction <= 20 µs",
            None if not ekf else ekf["correct_us"],
            20.0,
            "µs",
            "not measured",
        )
    )
    return targets


# -- text ------------------------------------------------------------------------------------------------------
def _ms(seconds) -> str:
    return "-" if seconds is None else f"{1e3 * seconds:.3f} ms"


def _value(target: dict) -> str:
    value = target["value"]
    if value is None:
        return "-"
    digits = 2 if abs(value) < 100 else 0
    return f"{value:,.{digits}f} {target['unit']}".strip()


def format_report(result: dict) -> str:
    m = result["machine"]
    flags = m.get("simd_flags") or {}
    simd = ", ".join(f"{name} {'yes' if flags.get(name) else 'no'}" for name in ("avx2", "avx512f")) if flags else "?"
    if "numba_svml" in m:
        simd += f"; SVML {'yes' if m['numba_svml'] else 'no'}"
    load = " ".join(f"{x:.2f}" for x in (m.get("load_average") or []))
    target = ""
    if m.get("numba_cpu_name") or m.get("numba_cpu_features"):
        target = (
            f"; kernels compiled for {m.get('numba_cpu_name') or 'this CPU'}"
            f"{' (' + m['numba_cpu_features'] + ')' if m.get('numba_cpu_features') else ''}, not this CPU"
        )
    lines = [
        f"robocup-mcl bench{' --quick' if result['settings']['quick'] else ''}: {m['cpu_model']}, "
        f"{m['cpus']} cores ({simd}); python {m['python']}, numpy {m['numpy']}, numba {m['numba']}; "
        f"load {load}{target}",
        "full step: predict (velocity-linear), 10 goalpost detections (von Mises bearing), normalize + ESS, "
        "systematic resampling with roughening, estimate, entropy; one thread; medians of single calls, each "
        "after calls of every other timed item (phases included)",
        "b2b: the full step called back to back (warm caches); fast: the full step with fast=True; issue "
        "shape, its fast: the issue's step shape (the C reference's: no roughening, no estimate) on the same "
        "kernels; inject: the full step when augmented MCL replaces 5 % of N every step; adaptive: the full "
        "step with the adaptive motion model; these six in ns per particle",
    ]
    avx = _section(result, "numpy_without_avx512")
    avx_rows = {r["n"]: r["numpy_s"] for r in avx["rows"]} if avx else {}
    lines.append(
        f"{'N':>9} {'numba':>11} {'ns/part.':>9} {'numpy':>12} {'speedup':>8} {'exact atan2':>12} "
        f"{'numpy no-AVX512':>16} {'speedup':>8} {'b2b':>6} {'fast':>6} {'issue shape':>12} {'its fast':>9} "
        f"{'inject':>7} {'adaptive':>9}"
    )

    def per_particle(entry) -> str:
        return "-" if not entry else f"{entry['numba_ns_per_particle']:.1f}"

    for row in result.get("rows", []):
        step = row["full_step"]
        exact = row.get("full_step_exact_bearing")
        no_avx = avx_rows.get(row["n"])
        no_avx_speedup = "-" if no_avx is None else f"{no_avx / step['numba_s']:.1f}x"
        lines.append(
            f"{row['n']:>9} {_ms(step['numba_s']):>11} {row['ns_per_particle']:>9.1f} "
            f"{_ms(step['numpy_s']):>12} {row['speedup']:>7.1f}x {_ms(exact and exact['numba_s']):>12} "
            f"{_ms(no_avx):>16} {no_avx_speedup:>8} {per_particle(row.get('full_step_back_to_back')):>6} "
            f"{per_particle(row.get('full_step_fast')):>6} "
            f"{per_particle(row.get('issue_step')):>12} {per_particle(row.get('issue_step_fast')):>9} "
            f"{per_particle(row.get('injecting_step')):>7} {per_particle(row.get('adaptive_step')):>9}"
        )
    if avx:
        ratios = ", ".join(f"N = {r['n']}: {r['off_over_on']:.2f}x" for r in avx["rows"])
        lines.append(
            f'  numpy no-AVX512: NPY_DISABLE_CPU_FEATURES="{avx["NPY_DISABLE_CPU_FEATURES"]}", fresh '
            f"processes alternated with numpy as it is (N <= 100 000); off / on: {ratios or '-'}"
            f"{'; ' + avx['note'] if avx.get('note') else ''}"
        )
    elif isinstance(result.get("numpy_without_avx512"), dict):
        lines.append(f"  numpy no-AVX512: {_failure(result['numpy_without_avx512'])}")

    sizes = [row["n"] for row in result.get("rows", [])]
    if sizes:
        lines.append("")
        lines.append("phases, ns per particle: numba / numpy (speedup); '-': no numpy twin")
        lines.append(f"{'phase':<24}" + "".join(f"{f'N = {n}':>24}" for n in sizes))
        for phase in PHASES:
            cells = []
            for row in result["rows"]:
                entry = row["phases"].get(phase.name)
                if entry is None or "error" in entry:
                    cells.append(f"{'skipped' if entry is None else 'FAILED':>24}")
                    continue
                text = _short(entry["numba_ns_per_particle"]) + " / "
                if entry["numpy_ns_per_particle"] is None:
                    text += "-"
                else:
                    text += f"{_short(entry['numpy_ns_per_particle'])} ({entry['speedup']:.1f}x)"
                cells.append(f"{text:>24}")
            lines.append(f"{phase.name:<24}" + "".join(cells))
        for row in result["rows"]:
            for name, entry in row["phases"].items():
                if "error" in entry:
                    lines.append(f"  {name} at N = {row['n']} failed: {entry['error']}")

    peers = _section(result, "resampling")
    if peers:
        lines.append("")
        lines.append(
            "systematic resampling, ns per particle (ratio to our fastest; > 1: ours is faster); each "
            "resampler called back to back, samples of about 20 ms"
        )
        peer_sizes = [r["n"] for r in peers["rows"]]
        lines.append(f"{'entry':<42}" + "".join(f"{f'N = {n}':>18}" for n in peer_sizes))
        for label, status in peers["entries"].items():
            if not status["available"]:
                lines.append(f"{label:<42}{status['note']}")
                continue
            cells = []
            for r in peers["rows"]:
                ns = r["ns_per_particle"].get(label)
                text = "failed" if ns is None else f"{_short(ns)} ({r['ratio_to_ours'][label]:.2f}x)"
                cells.append(f"{text:>18}")
            version = f" {status['version']}" if status.get("version") else ""
            lines.append(f"{(label + version)[:41]:<42}" + "".join(cells))
        for r in peers["rows"]:
            for label, problem in r["problems"].items():
                lines.append(f"  N = {r['n']}: {label}: {problem}")
    elif isinstance(result.get("resampling"), dict):
        lines.append(f"resampling peers: {_failure(result['resampling'])}")

    lines.append("")
    threads = result.get("threads")
    if isinstance(threads, dict) and threads.get("rows"):
        text = ", ".join(
            f"N = {r['n']}: {r['speedup']:.2f}x ({_ms(r['one_thread_s'])} -> {_ms(r['two_threads_s'])})"
            for r in threads["rows"]
        )
        lines.append(
            f"two threads versus one (ParticleFilter({threads['option']}=...), numba threading layer "
            f"{threads.get('threading_layer')}, {threads.get('cpus_usable')} cores usable): {text}"
            f"{'  (' + threads['note'] + ')' if threads.get('note') else ''}"
        )
    elif isinstance(threads, dict):
        lines.append(f"two threads versus one: {threads.get('note') or _failure(threads)}")

    memory = _section(result, "memory")
    if memory:
        for r in memory["rows"]:
            allocations = r["numba_allocations_per_step"]
            lines.append(
                f"memory at N = {r['n']:>7}: filter {r['filter_bytes'] / 1e6:.2f} MB; one step's scratch "
                f"(tracemalloc peak) {r['step_peak_bytes'] / 1e6:.3f} MB = "
                f"{r['step_peak_bytes_per_particle']:.1f} B/particle; kept per step "
                f"{r['retained_bytes_per_step']:.0f} B; numba allocations per step "
                f"{'?' if allocations is None else f'{allocations:.0f}'}"
            )
        lines.append(
            f"  step scratch grows with N: {'yes' if memory['grows_with_n'] else 'no'} "
            f"({memory['step_peak_ratio']:.1f}x from N = {memory['sizes'][0]:,} to {memory['sizes'][-1]:,}); "
            f"numba allocations grow with N: "
            f"{'yes' if memory.get('kernel_allocations_grow_with_n') else 'no'}"
        )
    elif isinstance(result.get("memory"), dict):
        lines.append(f"memory: {_failure(result['memory'])}")

    startup = _section(result, "startup")
    if startup:
        cold = (
            ""
            if startup["cold_cache_s"] is None
            else f"empty numba cache {startup['cold_cache_s']:.2f} s ({startup.get('kernels_compiled_cold')} kernels "
            f"compiled, compile ~ {startup['compile_s']:.2f} s), "
        )
        lines.append(
            f"start-up to the first step: {cold}cache found {startup['warm_cache_s']:.2f} s"
            f"{'  (' + startup['note'] + ')' if startup.get('note') else ''}"
        )
    elif isinstance(result.get("startup"), dict):
        lines.append(f"start-up: {_failure(result['startup'])}")
    walk = _section(result, "demo_walk")
    if walk:
        lines.append(
            f"{walk['command']} (cache found): {walk['wall_s']:.2f} s"
            f"{'  (' + walk['note'] + ')' if walk.get('note') else ''}"
        )
    elif isinstance(result.get("demo_walk"), dict):
        lines.append(f"demo walk: {_failure(result['demo_walk'])}")

    models = _section(result, "models")
    ratios = adaptive_ratios(result)
    if ratios:
        lines.append(
            "adaptive predict (the slower of collisions and quiet walking) / velocity-linear predict: "
            + ", ".join(f"N = {n}: {r:.2f}x" for n, r in ratios)
        )
    if models:
        lwpr, ekf = models.get("lwpr"), models.get("ekf")
        if lwpr:
            lines.append(
                f"LWPR, 2 inputs ({lwpr['receptive_fields']} receptive fields): update {lwpr['update_us']:.2f} µs, "
                f"predict {lwpr['predict_us']:.2f} µs (batched {lwpr['predict_batched_us_per_point']:.2f} µs/point)"
            )
        if ekf:
            lines.append(
                "velocity EKF: "
                + "; ".join(
                    f"{label} ({e['state_size']} states) predict {e['predict_us']:.2f} µs, correct {e['correct_us']:.2f} µs"
                    for label, e in ekf.items()
                )
            )
        loop = models.get("robot_loop")
        if loop:
            lines.append(
                f"robot loop (README), N = {loop['particles']}: a frame without detections (predict, "
                f"estimate, entropy) {loop['frame_us']:.1f} µs, predict alone {loop['predict_us']:.1f} µs, "
                f"correct with a list of 3 detections {loop['correct_list_us']:.1f} µs; a batch from 3 "
                f"LandmarkObservation {loop['from_list_us']:.1f} µs, from arrays of 10 "
                f"{loop['from_arrays_us']:.1f} µs; Localizer, walking: a frame (motion, pose, quality) "
                f"{loop['localizer_frame_us']:.1f} µs, observe 3 detections 30 ms old "
                f"{loop['localizer_observe_us']:.1f} µs"
                + (
                    f"; a frame of a young track (motion and observe, with its rival places) "
                    f"{loop['localizer_young_frame_us']:.1f} µs"
                    if "localizer_young_frame_us" in loop
                    else ""
                )
            )
        for key in ("lwpr_error", "ekf_error", "robot_loop_error"):
            if key in models:
                lines.append(f"{key[: -len('_error')]}: {models[key]}")
    frames = _section(result, "between_frames")
    if frames and frames["rows"]:
        warm = frames["back_to_back_us"]
        steps = "; ".join(
            f"N = {row['n']}: full step {row['full_step_us']:.1f} µs, the issue's step shape "
            f"{row['issue_step_us']:.1f} µs"
            for row in frames["rows"]
        )
        lines.append(
            f"between frames (one call after {1e3 * frames['idle_s']:g} ms asleep, as a 100 Hz loop makes "
            f"it; medians of {frames['samples']}): {steps}; the machine's baseline, a Python call that does "
            f"nothing {frames['python_call_us']:.1f} µs and a compiled call given one array "
            f"{frames['numba_call_us']:.1f} µs (back to back {warm['python_call']:.2f} and "
            f"{warm['numba_call']:.2f})"
        )
    elif "between_frames" in result:
        lines.append(f"between frames: {_failure(result['between_frames'])}")
    accuracy = _section(result, "bearing_accuracy")
    if accuracy:
        lines.append(
            f"von Mises versus exact bearing term: total-variation distance between the normalized weights "
            f"{accuracy['total_variation']:.4f} (N = {accuracy['n']}, same particles and detections)"
        )

    lines.append("")
    lines.append("targets")
    for t in result.get("targets", []):
        verdict = "not measured" if t["met"] is None else ("met" if t["met"] else "NOT MET")
        note = f"  ({t['note']})" if t["note"] else ""
        lines.append(f"  {verdict:<13} {t['target']:<72} {_value(t)}{note}")
    lines.append(f"total {result.get('duration_s', 0.0):.0f} s")
    return "\n".join(lines)


def _failure(section: dict) -> str:
    """A failed section's error in one line (the JSON keeps the whole message and a traceback)."""
    error = section.get("error")
    if not error:
        return "skipped"
    last = [line.strip() for line in error.strip().splitlines() if line.strip()][-1]
    head = error.split(":", 1)[0]
    return f"FAILED ({head}: {last})" if last != error.strip() else f"FAILED ({last[:300]})"


def _short(ns: float) -> str:
    if ns >= 1e4:
        return f"{ns / 1e3:.0f}k"
    return f"{ns:.1f}" if ns < 100 else f"{ns:.0f}"


# -- the plot --------------------------------------------------------------------------------------------------
def plot(result: dict, path: str) -> None:
    """Scaling curves, ns per particle against N (log-log): the full step, each phase, and resampling against
    the other libraries. Saved as PNG (matplotlib, Agg backend)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    rows = result.get("rows", [])
    sizes = [row["n"] for row in rows]
    figure, axes = plt.subplots(1, 3, figsize=(18, 6), constrained_layout=True)
    m = result["machine"]
    figure.suptitle(
        f"robocup-mcl bench: {m['cpu_model']}, python {m['python']}, numpy {m['numpy']}, "
        f"numba {m['numba']} (one thread)"
    )

    ax = axes[0]
    ax.plot(sizes, [row["ns_per_particle"] for row in rows], "o-", color="tab:blue", label="numba step")
    ax.plot(
        sizes, [row["full_step"]["numpy_ns_per_particle"] for row in rows], "s--", color="tab:red", label="numpy step"
    )
    for key, style, color, label in (
        ("full_step_fast", "o:", "tab:blue", "numba step, fast=True"),
        ("issue_step", "D-", "tab:purple", "issue's step shape (no roughening, no estimate)"),
        ("issue_step_fast", "D:", "tab:purple", "issue's step shape, fast=True"),
    ):
        points = [(row["n"], row[key]["numba_ns_per_particle"]) for row in rows if row.get(key)]
        if points:
            ax.plot(*zip(*points), style, color=color, label=label, ms=4)
    exact = [
        (row["n"], row["full_step_exact_bearing"]["numba_ns_per_particle"])
        for row in rows
        if row.get("full_step_exact_bearing")
    ]
    if exact:
        ax.plot(*zip(*exact), "^-", color="tab:cyan", label="numba step, exact atan2 bearing")
    avx = _section(result, "numpy_without_avx512")
    if avx and avx["rows"]:
        ax.plot(
            [r["n"] for r in avx["rows"]],
            [1e9 * r["numpy_s"] / r["n"] for r in avx["rows"]],
            "x:",
            color="tab:orange",
            label="numpy step, AVX-512 off",
        )
    for level, text in ((80, "target 80 ns (N >= 10^4)"), (40, "aim 40 ns")):
        ax.axhline(level, color="grey", lw=0.8, ls=":")
        ax.text(sizes[0] if sizes else 1, level * 1.08, text, color="grey", fontsize=8)
    ax.set_title("full step")

    ax = axes[1]
    palette = [matplotlib.colormaps["tab10"](i) for i in range(10)] + ["black", "olive"]
    for i, phase in enumerate(PHASES):
        points = [
            (row["n"], row["phases"][phase.name])
            for row in rows
            if "numba_ns_per_particle" in row["phases"].get(phase.name, {})
        ]
        if not points:
            continue
        color = palette[i % len(palette)]
        ax.plot(
            [n for n, _ in points],
            [e["numba_ns_per_particle"] for _, e in points],
            "o-",
            color=color,
            label=phase.name,
            ms=3,
        )
        twin = [(n, e["numpy_ns_per_particle"]) for n, e in points if e["numpy_ns_per_particle"] is not None]
        if twin:
            ax.plot(*zip(*twin), "--", color=color, lw=0.8)
    ax.set_title("phases: numba (solid) and numpy (dashed)")

    ax = axes[2]
    peers = _section(result, "resampling")
    if peers:
        for label, status in peers["entries"].items():
            points = [(r["n"], r["ns_per_particle"].get(label)) for r in peers["rows"]]
            points = [(n, v) for n, v in points if v is not None]
            if status["available"] and points:
                ours = status["package"] == "robocup-mcl" and "reference" not in label
                ax.plot(*zip(*points), "o-" if ours else "s--", label=label, lw=2 if ours else 1)
        ax.axhline(3.0, color="grey", lw=0.8, ls=":")
        ax.text(
            peers["rows"][-1]["n"] if peers["rows"] else 1,
            2.8,
            "target 3 ns at 10^6",
            color="grey",
            fontsize=8,
            ha="right",
            va="top",
        )
    ax.set_title("systematic resampling")

    for ax, where, columns in zip(axes, ("upper right", "upper right", "lower left"), (1, 2, 1)):
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel("particles N")
        ax.set_ylabel("ns per particle")
        ax.grid(True, which="both", lw=0.3)
        ax.legend(fontsize=7, loc=where, ncols=columns, framealpha=0.8)
    low, high = axes[1].get_ylim()
    axes[1].set_ylim(low, high * 6)  # room for the legends: above the phase curves,
    low, high = axes[2].get_ylim()
    axes[2].set_ylim(low / 8, high)  # below the resampling curves
    figure.savefig(path, dpi=110)
    plt.close(figure)


def matplotlib_missing() -> bool:
    import importlib.util

    return importlib.util.find_spec("matplotlib") is None
