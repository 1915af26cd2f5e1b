"""Learning the localizer's settings from a team's logs: the library behind `robocup-mcl tune` (`demos.tune`).

- `mcl.tools.tuning.space`: the space file (which profile settings, over which ranges);
- `mcl.tools.tuning.objective`: what a trial measures on one log or battery scenario, and how the cases combine
  ("truth": the battery's figures; "evidence": the detections' log evidence, no ground truth needed);
- `mcl.tools.tuning.search`: the Optuna study (resumable journal file, seeded) with each trial's cases as Ray tasks;
- `mcl.tools.tuning.report`: the report's table and plots.

Needs the `tune` extra (Ray, Optuna, matplotlib), installed from the clone: `pip install -e '.[tune]'`. The
profiles it writes (`mcl.profile`) need nothing more than the library.
"""

from mcl.tools.tuning.objective import OBJECTIVES, LogCase, combine, evaluate_case, summary, truth_figures
from mcl.tools.tuning.search import StudyOutcome, TuneError, TuneSettings, run_study, start_ray, tune
from mcl.tools.tuning.space import Parameter, SearchSpace, SpaceError

__all__ = [
    "OBJECTIVES",
    "LogCase",
    "Parameter",
    "SearchSpace",
    "SpaceError",
    "StudyOutcome",
    "TuneError",
    "TuneSettings",
    "combine",
    "evaluate_case",
    "run_study",
    "start_ray",
    "summary",
    "truth_figures",
    "tune",
]
