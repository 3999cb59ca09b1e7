"""Evaluation: a policy on every (context, weight, episode) of a suite, and its results."""

from morl_trl.evaluation.evaluator import MultiContextEvaluator, suite_contexts
from morl_trl.evaluation.results import ContextResult, EvaluationResult
from morl_trl.evaluation.video import record_context_videos

__all__ = ["MultiContextEvaluator", "suite_contexts", "EvaluationResult", "ContextResult", "record_context_videos"]
