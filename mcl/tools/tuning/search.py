"""The search: an Optuna study whose trials are evaluated as Ray tasks, one per case × filter seed.

    from mcl.tools.tuning import LogCase, SearchSpace, TuneSettings, run_study, start_ray
    settings = TuneSettings(cases=(LogCase("a.mcap"), LogCase("b.mcap")), space=SearchSpace.load("space.toml"),
                            objective="evidence", trials=40)
    start_ray()                                                    # an embedded local Ray, the machine's cores
    outcome = run_study(settings, study_path="study.journal")
    outcome.best_values                                            # {"sensor.outlier_weight": ..., ...}

The study. Optuna's TPE sampler (or CMA-ES, `sampler="cmaes"`) proposes each trial's parameters; the study is
kept in a journal file (`optuna.storages.JournalStorage`), so a run that is interrupted resumes where it stopped
when started again with the same settings and file (a trial that was running is marked failed and asked
again). The sampler is seeded afresh before each proposal from the settings' seed and the number of trials
completed so far, so the same seed gives the same study, resumed or not. The library's default of every tuned
setting that lies inside its range is the first trial: the search starts from the defaults, and the tuned
profile can only beat them on the training cases, not lose to them. A parameter set the library refuses
(a combination, such as alpha_slow above alpha_fast) is a failed trial and does not count.

The tasks. Each trial's parameter set runs on every case × filter seed as one Ray task (`max_retries`: a
worker that dies mid-task is replaced and the task runs again; its result is the same, since the task is a
pure function of its arguments). `parallel_trials` trials are proposed and evaluated at once (more tasks in
flight for a bigger cluster; the study then depends on that number too). Results are gathered in submission
order, so the trial's value does not depend on which worker finished first. Without an address, `start_ray`
starts an embedded local Ray with `workers` CPUs; with one, it joins that cluster. numba's kernels are
compiled (or loaded from numba's cache) once per worker process, by its first task: the tasks report which
were first, and the outcome says what that cost (`first_task_s` against `later_task_s`).

Fault injection for the tests: with `ROBOCUP_MCL_TUNE_CRASH_ONCE` set to a file path in the environment Ray's
workers start with, the first task to run kills its worker process (`os._exit`) after creating that file.
"""

from __future__ import annotations

import math
import os
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from dataclasses import field as dataclass_field
from typing import Any

import numpy as np

from mcl.numba_cache import serialize_cache_access
from mcl.profile import Profile, ProfileError, default_values
from mcl.tools.cli_checks import CommandError
from mcl.tools.tuning.objective import OBJECTIVES, combine, evaluate_case, summary
from mcl.tools.tuning.space import SearchSpace

STUDY_NAME = "robocup-mcl-tune"
SAMPLERS = ("tpe", "cmaes")
CRASH_VARIABLE = "ROBOCUP_MCL_TUNE_CRASH_ONCE"
MAX_RETRIES = 3
_WORKER = {"tasks": 0}


class TuneError(CommandError):
    """A study that cannot run as asked (one line; a `mcl.tools.cli_checks.CommandError`, so the command prints it as
    `robocup-mcl: <message>` and exits 1): an unreachable cluster, a study file made for other settings, every
    trial refused."""


@dataclass(frozen=True)
class TuneSettings:
    """What a study searches (see the module docstring): training `cases`, the `space`, the `objective`
    ("truth" or "evidence"), completed `trials` to reach, filter `seeds` per case, the `sampler` and its
    `seed`, `particles` and `parallel_trials`. A case is a `LogCase` or anything with its `label` and
    `evaluate` (`mcl.tools.tuning.objective`)."""

    cases: tuple[Any, ...]
    space: SearchSpace
    objective: str
    trials: int
    seeds: tuple[int, ...] = (0,)
    sampler: str = "tpe"
    seed: int = 0
    particles: int = 500
    parallel_trials: int = 1

    def __post_init__(self) -> None:
        if not self.cases:
            raise ValueError("no case to tune on: give logs or battery seeds")
        if self.objective not in OBJECTIVES:
            raise ValueError(f"objective = {self.objective!r} must be one of {', '.join(OBJECTIVES)}")
        if self.sampler not in SAMPLERS:
            raise ValueError(f"sampler = {self.sampler!r} must be one of {', '.join(SAMPLERS)}")
        for name in ("trials", "parallel_trials", "particles"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int) or value < 1:
                raise ValueError(f"{name} = {value!r} must be an integer >= 1")
        if not self.seeds:
            raise ValueError("seeds: at least one filter seed")

    def fingerprint(self) -> dict:
        """What makes a study: a journal file is resumed only with the same fingerprint."""
        return {
            "cases": [repr(c) for c in self.cases],
            "space": self.space.to_dict(),
            "objective": self.objective,
            "seeds": list(self.seeds),
            "sampler": self.sampler,
            "seed": self.seed,
            "particles": self.particles,
            "parallel_trials": self.parallel_trials,
        }


@dataclass
class TaskLog:
    """Per task: its case label, trial, seconds inside the task, the worker's process id and node, and
    whether it was the worker's first task."""

    rows: list = dataclass_field(default_factory=list)

    def add(self, result: dict, label: str, trial: int | str) -> None:
        self.rows.append(
            {
                "case": label,
                "trial": trial,
                "seconds": result["seconds"],
                "pid": result["pid"],
                "node": result["node"],
                "first": result["first_in_worker"],
            }
        )

    def costs(self) -> dict:
        """The first-task cost: the mean seconds of the workers' first tasks against the median of the rest."""
        first = [r["seconds"] for r in self.rows if r["first"]]
        later = [r["seconds"] for r in self.rows if not r["first"]]
        return {
            "tasks": len(self.rows),
            "workers_seen": len({(r["node"], r["pid"]) for r in self.rows}),
            "nodes_seen": len({r["node"] for r in self.rows}),
            "first_task_s": float(np.mean(first)) if first else None,
            "later_task_s": float(np.median(later)) if later else None,
        }


def _task(case: Any, values: dict, seed: int, particles: int) -> dict:
    """One Ray task: `evaluate_case`, with the worker's bookkeeping (see the module docstring)."""
    marker = os.environ.get(CRASH_VARIABLE)
    if marker:
        try:
            fd = os.open(marker, os.O_CREAT | os.O_EXCL | os.O_WRONLY)
        except FileExistsError:
            pass
        else:
            os.close(fd)
            os._exit(1)  # the worker dies mid-task; Ray retries the task elsewhere
    first = _WORKER["tasks"] == 0
    _WORKER["tasks"] += 1
    if first:  # the workers compile the same kernels into one cache side by side
        serialize_cache_access()
    result = evaluate_case(case, values, seed, particles)
    import ray

    result.update(pid=os.getpid(), node=ray.get_runtime_context().get_node_id(), first_in_worker=first)
    return result


_REMOTE: dict[str, Any] = {}


def remote_task():
    """The Ray remote function of one task (case, values, seed, particles) -> `evaluate_case`'s figures with the
    worker's process id, node and whether it was its first task; retried `MAX_RETRIES` times if its worker dies.
    Ray must be started."""
    if "task" not in _REMOTE:
        import ray

        _REMOTE["task"] = ray.remote(num_cpus=1, max_retries=MAX_RETRIES)(_task)
    return _REMOTE["task"]


def start_ray(address: str | None = None, workers: int | None = None) -> dict:
    """Connect to the Ray cluster at `address`, or start an embedded local one with `workers` CPUs (default:
    the machine's); returns {"address", "cpus", "nodes", "seconds"}. TuneError when the cluster cannot be
    reached. Nothing happens when Ray is already initialized in this process."""
    import ray

    started = time.perf_counter()
    if not ray.is_initialized():
        options: dict[str, Any] = {
            "include_dashboard": False,
            "log_to_driver": False,
            "logging_level": "ERROR",
            "configure_logging": True,
        }
        try:
            if address:
                ray.init(address=address, **options)
            else:
                # "local": a new embedded instance even where another process runs one (with no address Ray
                # would join the newest cluster on this machine, whose CPUs it may not set)
                ray.init(address="local", num_cpus=workers or os.cpu_count() or 1, **options)
        except (ConnectionError, RuntimeError, ValueError, TimeoutError) as error:
            text = " ".join(str(error).split()) or type(error).__name__
            raise TuneError(
                f"cannot reach the Ray cluster at {address}: {text[:200]}"
                if address
                else f"cannot start a local Ray instance: {text[:200]}"
            ) from None
    resources = ray.cluster_resources()
    return {
        "address": address or "local",
        "cpus": int(resources.get("CPU", 0)),
        "nodes": len([n for n in ray.nodes() if n.get("Alive")]),
        "seconds": time.perf_counter() - started,
    }


def check_address(address: str, timeout: float = 5.0) -> None:
    """TuneError unless something listens at `address` ("host:port"; ray:// or a bare "auto" are left to Ray),
    before Ray is asked to connect (its own timeout is a minute)."""
    import socket

    if address == "auto" or "://" in address:
        return
    host, _, port = address.rpartition(":")
    try:
        number = int(port)
    except ValueError:
        raise TuneError(f"--address {address!r} must be HOST:PORT (the Ray head's GCS address)") from None
    try:
        with socket.create_connection((host or "127.0.0.1", number), timeout=timeout):
            pass
    except OSError as error:
        raise TuneError(f"cannot reach the Ray cluster at {address}: {error.strerror or error}") from None


def evaluate_many(jobs: Sequence[tuple[Any, dict, int]], settings: TuneSettings) -> list[dict]:
    """Every (case, values, seed) as a Ray task; the results in the order given."""
    import ray

    task = remote_task()
    refs = [task.remote(case, values, seed, settings.particles) for case, values, seed in jobs]
    return ray.get(refs)


def _sampler(kind: str, seed: int):
    import optuna

    if kind == "cmaes":
        return optuna.samplers.CmaEsSampler(seed=seed, warn_independent_sampling=False)
    return optuna.samplers.TPESampler(seed=seed)


@dataclass
class StudyOutcome:
    """A finished study: the completed trials (number, value, values, figures), the best, the task costs."""

    trials: list[dict]
    best_values: dict[str, Any]
    best_value: float
    best_trial: int
    importance: dict[str, float]
    tasks: TaskLog
    resumed: int
    failed: int
    seconds: float


def _open_study(settings: TuneSettings, study_path: str | None):
    import optuna
    from optuna.storages import JournalStorage
    from optuna.storages.journal import JournalFileBackend

    optuna.logging.set_verbosity(optuna.logging.WARNING)
    storage = JournalStorage(JournalFileBackend(study_path)) if study_path else None
    study = optuna.create_study(
        storage=storage,
        study_name=STUDY_NAME,
        direction="minimize",
        sampler=_sampler(settings.sampler, settings.seed),
        load_if_exists=True,
    )
    fingerprint = settings.fingerprint()
    made_for = study.user_attrs.get("settings")
    if made_for is None:
        study.set_user_attr("settings", fingerprint)
        defaults = default_values(settings.particles)
        start = {}
        for p in settings.space.parameters:
            value = defaults.get(p.name)
            if p.choices and value in p.choices or not p.choices and value is not None and p.low <= value <= p.high:
                start[p.name] = value
        if start:
            study.enqueue_trial(start, user_attrs={"start": "library defaults"})
    elif made_for != fingerprint:
        changed = sorted(k for k in fingerprint if fingerprint[k] != made_for.get(k))
        raise TuneError(
            f"the study file {study_path} was made for other settings ({', '.join(changed)} differ): "
            "give another --study file, or the same settings to resume it"
        )
    return study


def run_study(
    settings: TuneSettings, study_path: str | None = None, on_trial: Callable[[dict], None] | None = None
) -> StudyOutcome:
    """Run (or resume) the study until `settings.trials` trials have completed; Ray must be started
    (`start_ray`). `on_trial` is called with each completed trial's row (for a progress bar)."""
    import optuna
    from optuna.trial import TrialState

    started = time.perf_counter()
    study = _open_study(settings, study_path)
    for trial in study.get_trials(deepcopy=False, states=(TrialState.RUNNING,)):
        study.tell(trial.number, state=TrialState.FAIL)  # interrupted mid-trial: asked again below
    resumed = len(study.get_trials(deepcopy=False, states=(TrialState.COMPLETE,)))
    distributions = settings.space.distributions()
    tasks = TaskLog()
    failed = 0
    while True:
        complete = len(study.get_trials(deepcopy=False, states=(TrialState.COMPLETE,)))
        if complete >= settings.trials:
            break
        refused = sum("refused" in t.user_attrs for t in study.get_trials(deepcopy=False, states=(TrialState.FAIL,)))
        batch = []
        for b in range(min(settings.parallel_trials, settings.trials - complete)):
            study.sampler = _sampler(settings.sampler, settings.seed * 1_000_003 + complete + refused + b)
            trial = study.ask(distributions)
            values = dict(trial.params)
            try:
                Profile.from_values(values)
            except ProfileError as error:
                trial.set_user_attr("refused", str(error))
                study.tell(trial, state=TrialState.FAIL)
                failed += 1
                if failed >= max(10, settings.trials):
                    raise TuneError(
                        f"{failed} parameter sets refused by the library (the last: {error}); narrow the space"
                    ) from None
                continue
            batch.append((trial, values))
        if not batch:
            continue
        jobs = [(case, values, seed) for _, values in batch for case in settings.cases for seed in settings.seeds]
        results = evaluate_many(jobs, settings)
        per_trial = len(settings.cases) * len(settings.seeds)
        for i, (trial, values) in enumerate(batch):
            chunk = results[i * per_trial : (i + 1) * per_trial]
            for (case, _, _), result in zip(jobs[i * per_trial : (i + 1) * per_trial], chunk):
                tasks.add(result, case.label, trial.number)
            value = combine(settings.objective, chunk)
            figures = summary(chunk)
            trial.set_user_attr("figures", figures)
            study.tell(trial, value if math.isfinite(value) else 1e12)
            if on_trial is not None:
                on_trial({"number": trial.number, "value": value, "values": values, "figures": figures})
    rows = []
    for t in study.get_trials(deepcopy=False, states=(TrialState.COMPLETE,)):
        rows.append(
            {
                "number": t.number,
                "value": t.value,
                "values": dict(t.params),
                "figures": t.user_attrs.get("figures"),
                "start": t.user_attrs.get("start"),
            }
        )
    rows.sort(key=lambda r: r["number"])
    best = min(rows, key=lambda r: (r["value"], r["number"]))
    try:
        importance = (
            {
                k: float(v)
                for k, v in optuna.importance.get_param_importances(
                    study, evaluator=optuna.importance.PedAnovaImportanceEvaluator()
                ).items()
            }
            if len(rows) >= 2 and len(settings.space.parameters) > 1
            else {}
        )
    except (RuntimeError, ValueError, ZeroDivisionError):
        importance = {}
    return StudyOutcome(
        rows,
        best["values"],
        best["value"],
        best["number"],
        importance,
        tasks,
        resumed,
        failed,
        time.perf_counter() - started,
    )


def tune(
    settings: TuneSettings,
    holdout: Sequence[Any] = (),
    study_path: str | None = None,
    on_trial: Callable[[dict], None] | None = None,
) -> dict:
    """`run_study`, then the library's defaults and the best parameter set on the training and the `holdout`
    cases (every filter seed); returns the JSON-ready result: "trials", "best", "defaults", "importance",
    "comparison" (per split the default's and the tuned set's `summary`, and per case), "ray" (the task costs),
    "evidence_vs_error" (the evidence objective with truth in the cases: Spearman's rank correlation over the
    trials of the evidence per frame and the truth loss), "study_s" and "trials_per_hour". Ray must be started.
    """
    from mcl.tools.tuning.report import spearman

    started = time.perf_counter()
    outcome = run_study(settings, study_path, on_trial)
    study_seconds = time.perf_counter() - started
    compare: dict = {}
    per = len(settings.seeds)
    for split, cases in (("training", tuple(settings.cases)), ("holdout", tuple(holdout))):
        if not cases:
            continue
        jobs = [
            (case, values, seed) for values in ({}, outcome.best_values) for case in cases for seed in settings.seeds
        ]
        results = evaluate_many(jobs, settings)
        for (case, _, _), row in zip(jobs, results):
            outcome.tasks.add(row, case.label, "comparison")
        half = len(results) // 2
        compare[split] = {
            "default": summary(results[:half]),
            "tuned": summary(results[half:]),
            "per_case": [
                {
                    "case": case.label,
                    "default": summary(results[i * per : (i + 1) * per]),
                    "tuned": summary(results[half + i * per : half + (i + 1) * per]),
                }
                for i, case in enumerate(cases)
            ],
        }
    new_trials = len(outcome.trials) - outcome.resumed
    defaults = default_values(settings.particles)
    result: dict = {
        "ray": outcome.tasks.costs(),
        "resumed": outcome.resumed,
        "failed": outcome.failed,
        "trials": outcome.trials,
        "best": {"trial": outcome.best_trial, "value": outcome.best_value, "values": outcome.best_values},
        "defaults": {name: defaults.get(name) for name in settings.space.names},
        "importance": outcome.importance,
        "comparison": compare,
        "study_s": study_seconds,
        "trials_per_hour": 3600.0 * new_trials / study_seconds if new_trials and study_seconds > 0 else 0.0,
    }
    if settings.objective == "evidence":
        pairs = [
            (t["figures"].get("evidence_per_frame"), t["figures"].get("truth_loss"))
            for t in outcome.trials
            if t["figures"]
        ]
        if pairs and all(b is not None for _, b in pairs):
            result["evidence_vs_error"] = {
                "trials": len(pairs),
                "spearman": spearman([a for a, _ in pairs], [b for _, b in pairs]),
            }
    return result
