"""The hypervolume reference point of a Gymnasium / MO-Gymnasium id, by one rule a user can predict.

MO-Gymnasium documents no reference points. For an id, the first of these that applies gives
each objective's value (``reference_point`` returns the point and a line saying where it
comes from, which the run prints at its start and writes in its report):

1. **MORL-Baselines' convention**: the point MORL-Baselines' examples and tests evaluate the
   id with (:data:`MO_GYMNASIUM_REF_POINTS`, each with its file), for the whole point.
2. **The reward bounds**: for an objective whose ``reward_space`` low is finite,
   ``horizon x min(low, 0) - 1`` (``horizon``: the id's ``max_episode_steps``). No return,
   discounted or not, is below ``horizon x min(low, 0)``: every step's reward is at least
   ``low``, and an objective whose rewards are never negative (``low >= 0``) has -1, whatever
   the horizon. The ``- 1`` makes a return on the bound (an objective never scored, a time
   penalty paid at every step) still add hypervolume.
3. **A random rollout**, for an objective whose low is ``-inf`` (or negative without a
   horizon): :data:`ROLLOUT_EPISODES` episodes of uniformly random actions (episode ``i``
   seeded ``i``, at most ``horizon`` or :data:`ROLLOUT_MAX_STEPS` steps), the lowest
   undiscounted return ``m`` of the objective, with a margin: ``floor(1.1 min(m, 0)) - 1``
   (never above -1: a random policy's short episodes say little about how low a return can go).

A user's point (``--ref-point``, ``ref_point=``) replaces the whole rule.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

__all__ = ["MO_GYMNASIUM_REF_POINTS", "ROLLOUT_EPISODES", "ROLLOUT_MAX_STEPS", "reference_point",
           "bounds_reference_point", "rollout_margin"]

#: MO-Gymnasium id -> (hypervolume reference point, where it comes from): the points
#: MORL-Baselines (LucasAlegre/morl-baselines) evaluates these envs with.
MO_GYMNASIUM_REF_POINTS: dict[str, tuple[tuple[float, ...], str]] = {
    "deep-sea-treasure-v0": ((0.0, -25.0), "MORL-Baselines examples/pql_dst.py and tests/test_algos.py (mp_mo_q_learning)"),
    "deep-sea-treasure-concave-v0": ((0.0, -25.0), "MORL-Baselines examples/pql_dst.py (the concave map)"),
    "minecart-v0": ((0.0, 0.0, -200.0), "MORL-Baselines examples/envelope_minecart.py and tests/test_algos.py"),
    "minecart-deterministic-v0": ((0.0, 0.0, -200.0), "MORL-Baselines tests/test_algos.py (test_pcn)"),
    "minecart-rgb-v0": ((0.0, 0.0, -200.0), "MORL-Baselines examples/envelope_minecart.py (minecart-v0; the same env "
                        "with image observations)"),
    "mo-hopper-v4": ((-100.0, -100.0, -100.0), "MORL-Baselines examples/capql_hopper.py"),
    "mo-hopper-v5": ((-100.0, -100.0, -100.0), "MORL-Baselines examples/capql_hopper.py (mo-hopper-v4; v5 has the same rewards)"),
    "mo-hopper-2obj-v5": ((-100.0, -100.0), "MORL-Baselines examples/mopac_hopper_2obj.py"),
    "mo-halfcheetah-v4": ((-100.0, -100.0), "MORL-Baselines examples/morld_cheetah.py"),
    "mo-halfcheetah-v5": ((-100.0, -100.0), "MORL-Baselines examples/morld_cheetah.py (mo-halfcheetah-v4; v5 has the same rewards)"),
    "mo-lunar-lander-v3": ((-101.0, -1001.0, -101.0, -101.0), "MORL-Baselines examples/morld_lunar_lander.py"),
    "mo-lunar-lander-continuous-v3": ((-101.0, -1001.0, -101.0, -101.0), "MORL-Baselines examples/morld_lunar_lander.py "
                                      "(mo-lunar-lander-v3; the continuous env has the same rewards)"),
    "mo-mountaincarcontinuous-v0": ((-1000.0, -1000.0), "MORL-Baselines examples/morld_continuous_mountain_car.py"),
    # every fruit value is >= 0 (reward_space low = 0), so every return dominates the origin (rule 2)
    "fruit-tree-v0": ((0.0,) * 6, "derived: MO-Gymnasium's reward_space of fruit-tree-v0 is [0, 10]^6"),
}

#: rule 3: random episodes, and the most steps of one
ROLLOUT_EPISODES = 5
ROLLOUT_MAX_STEPS = 1000


def bounds_reference_point(low: Sequence[float], horizon: int | None) -> list[float | None]:
    """Rule 2 per objective: ``horizon * min(low, 0) - 1``; ``None`` where it does not apply
    (an infinite low, or a negative low without a horizon).

    Example:
        >>> bounds_reference_point([-1.0, 0.0, 0.5], 100)
        [-101.0, -1.0, -1.0]
        >>> bounds_reference_point([float("-inf"), -1.0, 0.0], None)
        [None, None, -1.0]
    """
    out: list[float | None] = []
    for lo in low:
        lo = float(lo)
        if lo >= 0:
            out.append(-1.0)
        elif math.isfinite(lo) and horizon:
            out.append(float(horizon) * lo - 1.0)
        else:
            out.append(None)
    return out


def rollout_margin(lowest: float) -> float:
    """Rule 3's value from the lowest random return ``lowest``: ``floor(1.1 min(m, 0)) - 1``.

    Example:
        >>> rollout_margin(-250.4), rollout_margin(-0.5), rollout_margin(40.0)
        (-277.0, -2.0, -1.0)
    """
    return float(math.floor(1.1 * min(lowest, 0.0)) - 1)


def _lowest_random_returns(env, horizon: int | None) -> np.ndarray:
    """Per objective, the lowest undiscounted return of rule 3's random episodes of ``env``."""
    cap = min(horizon or ROLLOUT_MAX_STEPS, ROLLOUT_MAX_STEPS)
    env.action_space.seed(0)
    lowest = None
    for episode in range(ROLLOUT_EPISODES):
        env.reset(seed=episode)
        total = None
        for _ in range(cap):
            _, reward, terminated, truncated, _ = env.step(env.action_space.sample())
            reward = np.asarray(reward, dtype=np.float64)
            total = reward if total is None else total + reward
            if terminated or truncated:
                break
        lowest = total if lowest is None else np.minimum(lowest, total)
    return lowest


def reference_point(env_id: str, env_kwargs: dict | None = None,
                    horizon: int | None = None) -> tuple[tuple[float, ...], str]:
    """The reference point of a Gymnasium / MO-Gymnasium id by the rule of the module docstring,
    and where it comes from.

    Example:
        >>> reference_point("resource-gathering-v0", horizon=100)
        ((-101.0, -1.0, -1.0), 'derived: horizon 100 x min(reward_space low, 0) - 1 per objective')
    """
    if env_id in MO_GYMNASIUM_REF_POINTS and not env_kwargs:
        return MO_GYMNASIUM_REF_POINTS[env_id]
    from morl_trl.envs.gym_make import make_gym_env

    env = make_gym_env(env_id, env_kwargs)
    try:
        space = getattr(env.unwrapped, "reward_space", None)
        if space is None:
            raise ValueError(f"{env_id} declares no reward_space: a multi-objective env gives a vector reward [k] "
                             f"with k >= 2 (MO-Gymnasium envs do; a Gymnasium env with a scalar reward is "
                             f"single-objective)")
        low = np.asarray(space.low, dtype=np.float64).reshape(-1)
        point = bounds_reference_point(low.tolist(), horizon)
        missing = [i for i, v in enumerate(point) if v is None]
        if missing:
            lowest = _lowest_random_returns(env, horizon)
            for i in missing:
                point[i] = rollout_margin(float(lowest[i]))
    finally:
        env.close()
    parts = []
    if len(missing) < len(point):
        parts.append(f"horizon {horizon} x min(reward_space low, 0) - 1" if horizon
                     else "reward_space low >= 0: -1")
        if missing:
            parts[-1] += f" for objectives {[i for i in range(len(point)) if i not in missing]}"
    if missing:
        parts.append(f"for objectives {missing} (reward_space low -inf"
                     + ("" if horizon else " or no horizon") + f"): floor(1.1 min(m, 0)) - 1 of the lowest return m "
                     f"of {ROLLOUT_EPISODES} uniformly random episodes (seeds 0-{ROLLOUT_EPISODES - 1})")
    what = "; ".join(parts) + ("" if missing else " per objective")
    return tuple(float(v) for v in point), f"derived: {what}"
