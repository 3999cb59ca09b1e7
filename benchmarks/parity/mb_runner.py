"""One MORL-Baselines 1.3.0 run of a parity case (run by run_parity.py inside MB's own venv).

    python mb_runner.py CASE SEED OUT_JSON

Trains MB's class with the case's hyperparameters and evaluates it every ``eval_every`` steps
with the shared evaluation (``common.evaluate_act``: morl_trl's evaluator on the same env,
weights, discount and seed as our runs). Training time is measured without the evaluations.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

import numpy as np  # noqa: E402

from common import CASES, EVAL_EPISODES, MB_VERSION, evaluate_act, write_result  # noqa: E402


def _act(agent):
    def act(obs, w):
        return [int(agent.eval(o, wi)) for o, wi in zip(obs, w)]

    return act


def run(case_name: str, seed: int, out: Path) -> None:
    import mo_gymnasium as mo_gym
    import torch

    import morl_baselines
    from morl_baselines.common.evaluation import policy_evaluation_mo, seed_everything

    case = CASES[case_name]
    seed_everything(seed)
    torch.set_num_threads(1)
    env, eval_env = mo_gym.make(case["env"]), mo_gym.make(case["env"])
    curve, train_s = [], 0.0

    def evaluate(frames: int) -> None:
        t = time.perf_counter()
        m = evaluate_act(_act(agent), case["env"], case["gamma"], seed)
        curve.append(dict(frames=frames, eval_seconds=time.perf_counter() - t, **m))
        print(f"[mb {case_name} s{seed}] {frames} frames: {m}", flush=True)

    if case["algo"] == "gpi_ls":
        from morl_baselines.common.weights import equally_spaced_weights  # noqa: F401  (MB's own loop below)
        from morl_baselines.multi_policy.gpi_pd.gpi_pd import GPILS
        from morl_baselines.multi_policy.linear_support.linear_support import LinearSupport

        agent = GPILS(env, gamma=case["gamma"], log=False, seed=seed, **case["mb"])  # (no weight support before
        # the first iteration, so no evaluation at frame 0)
        per_iter = case["mb_train"]["timesteps_per_iter"]
        # GPIPD.train's loop (weight_selection_algo "gpi-ls"), with the shared evaluation after each iteration
        ls = LinearSupport(num_objectives=agent.reward_dim, epsilon=None)
        for _ in range(case["frames"] // per_iter):
            t = time.perf_counter()
            agent.set_weight_support(ls.get_weight_support())
            use_gpi, agent.use_gpi = agent.use_gpi, True
            w = ls.next_weight(algo="gpi-ls", gpi_agent=agent, env=eval_env, rep_eval=5)
            agent.use_gpi = use_gpi
            if w is None:
                break
            M = ls.get_weight_support() + ls.get_corner_weights(top_k=4) + [w]
            agent.train_iteration(total_timesteps=per_iter, weight=w, weight_support=M, change_w_every_episode=True,
                                  eval_env=eval_env, eval_freq=10 ** 9, reset_num_timesteps=False,
                                  reset_learning_starts=False)
            for wcw in M:
                ls.add_solution(policy_evaluation_mo(agent, eval_env, wcw, rep=5)[3], wcw)
            train_s += time.perf_counter() - t
            agent.set_weight_support(ls.get_weight_support())
            evaluate(agent.global_step)
    elif case["algo"] == "envelope":
        from morl_baselines.multi_policy.envelope.envelope import Envelope

        agent = Envelope(env, gamma=case["gamma"], log=False, seed=seed, **case["mb"])
        evaluate(0)
        done = 0
        while done < case["frames"]:
            t = time.perf_counter()
            agent.train(total_timesteps=case["eval_every"], eval_env=eval_env, ref_point=np.zeros(agent.reward_dim),
                        reset_num_timesteps=False, eval_freq=10 ** 9, **case["mb_train"])
            train_s += time.perf_counter() - t
            done += case["eval_every"]
            evaluate(agent.global_step)
    else:
        raise SystemExit(f"no MB runner for {case['algo']} yet")
    frames = curve[-1]["frames"]
    write_result(out, dict(case=case_name, lib="mb", seed=seed, version=f"morl-baselines {morl_baselines.__version__}"
                           if hasattr(morl_baselines, "__version__") else f"morl-baselines {MB_VERSION}",
                           curve=curve, frames=frames, train_seconds=train_s,
                           train_fps=frames / train_s if train_s else None, eval_episodes=EVAL_EPISODES))


if __name__ == "__main__":
    run(sys.argv[1], int(sys.argv[2]), Path(sys.argv[3]))
