"""Evaluation: a policy on every (context, weight, episode) of a suite, and its results."""

from morl_trl.evaluation.evaluator import MultiContextEvaluator, domain_env_factory
from morl_trl.evaluation.results import ContextResult, EvaluationResult

__all__ = ["MultiContextEvaluator", "domain_env_factory", "EvaluationResult", "ContextResult"]
