"""Preference-aware collection and the multi-context evaluator."""

from morl_trl.collectors.evaluator import MultiContextEvaluator
from morl_trl.collectors.results import ContextResult, EvaluationResult

__all__ = ["MultiContextEvaluator", "EvaluationResult", "ContextResult"]
