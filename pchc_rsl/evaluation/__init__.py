"""The paper's evaluation as a library: a policy at fixed preferences under the task's evaluation preset, Pareto
metrics, Table I / II with the gait, dynamic preference switching, and deployment shifts.

Works on any env that follows the contract (set_preference, extras["episode_metrics"] at episode ends); the task
specifics (which metrics form the front, the table columns, the evaluation preset) are in ``presets``. The CLIs
(pchc-eval, pchc-play) and the tools only parse their arguments and call these. Imported by their paths: training
curves (``training_plots``, for pchc-runs curves) and a mixture actor's expert usage (``expert_usage``).
"""

from pchc_rsl.evaluation.checkpoint import (TOY_STEPS_PER_SECOND, check_objectives, evaluate_checkpoint,
                                            evaluation_config, load_policy, loaded_policy, task_config_of,
                                            trained_preference)
from pchc_rsl.evaluation.presets import (
    FALL_RECOVERY_EVALUATION,
    TASK_EVALUATION,
    TOY_EVALUATION,
    WALK_EVALUATION,
    TaskEvaluation,
    evaluation_preset,
    evenly_spaced_preferences,
)
from pchc_rsl.evaluation.report import format_metric, front_points, front_summary, markdown_table, write_outputs
from pchc_rsl.evaluation.robustness import Condition, default_conditions, run_robustness, write_robustness
from pchc_rsl.evaluation.runs import run_episodes, run_return_episodes, settle_time, steady_walk, switching_run
from pchc_rsl.evaluation.statistics import RATE_METRICS, aggregate, wilson_interval

__all__ = [
    "Condition", "FALL_RECOVERY_EVALUATION", "TOY_STEPS_PER_SECOND", "check_objectives", "load_policy", "RATE_METRICS", "TASK_EVALUATION", "TOY_EVALUATION", "TaskEvaluation",
    "WALK_EVALUATION", "aggregate", "default_conditions", "evaluate_checkpoint", "evaluation_config",
    "evaluation_preset", "evenly_spaced_preferences", "format_metric", "front_points", "front_summary",
    "loaded_policy", "markdown_table", "run_episodes", "run_return_episodes", "run_robustness", "settle_time",
    "steady_walk", "switching_run", "task_config_of", "trained_preference", "wilson_interval", "write_outputs",
    "write_robustness",
]
