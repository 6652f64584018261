"""The learning runs' helpers under their earlier path: they live in `tavc_agents.learning_runs`."""

from tavc_agents.learning_runs import (
    DEFAULT_OPTIONS,
    EVAL_SEED,
    FINAL_SEEDS_FROM,
    REWARD_SCALE,
    CurveRow,
    Evaluation,
    LearningRun,
    RunOptions,
    evaluate_network,
    plot_curve,
    training_arena,
    what_it_learned,
    write_learning_run,
)

__all__ = [
    "DEFAULT_OPTIONS",
    "EVAL_SEED",
    "FINAL_SEEDS_FROM",
    "REWARD_SCALE",
    "CurveRow",
    "Evaluation",
    "LearningRun",
    "RunOptions",
    "evaluate_network",
    "plot_curve",
    "training_arena",
    "what_it_learned",
    "write_learning_run",
]
