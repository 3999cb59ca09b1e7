"""What both libraries share in the parity benchmark: the cases, the evaluation, the result files.

Imported by ``run_parity.py`` (our python) and by ``mb_runner.py`` (MORL-Baselines' virtual
environment, which sees morl_trl through ``PYTHONPATH``): one evaluation code path for both.
"""

from __future__ import annotations

import json
import os
import tempfile
from pathlib import Path

import numpy as np

MB_VERSION = "1.3.0"

# One case = one env, one algorithm, one set of hyperparameters given to both libraries (their
# names in each), one frame budget and one evaluation protocol. `ours` are TrainConfig keys,
# `mb` keyword arguments of the MORL-Baselines class. Budgets are where MB learns on a 2-core CPU.
CASES: dict[str, dict] = {
    # GPI-LS on Deep Sea Treasure: MB's GPILS with [64, 64], batch 32, one update per step reaches
    # 84-96 % of the true front's hypervolume in 30k steps (~2 min a seed on a free core)
    "gpi_ls-dst": dict(
        env="deep-sea-treasure-v0", algo="gpi_ls", frames=30_000, eval_every=10_000, gamma=0.99,
        ours=dict(hidden=[64, 64], batch_size=32, gpi_gradient_updates=1, gpi_iteration_frames=10_000),
        mb=dict(net_arch=[64, 64], batch_size=32, gradient_updates=1),
        mb_train=dict(timesteps_per_iter=10_000),
    ),
    # Envelope on Deep Sea Treasure at MB's default size ([256]*4, batch 256, 4 sampled weights)
    "envelope-dst": dict(
        env="deep-sea-treasure-v0", algo="envelope", frames=30_000, eval_every=10_000, gamma=0.99,
        ours=dict(), mb=dict(), mb_train=dict(),
    ),
}
if os.environ.get("PARITY_SMOKE"):  # a check of the machinery: every case cut to a few hundred frames
    for _c in CASES.values():
        _c.update(frames=200, eval_every=100)
        _c["mb_train"] = {k: (100 if k == "timesteps_per_iter" else v) for k, v in _c["mb_train"].items()}
        _c["ours"] = {**_c["ours"], **({"gpi_iteration_frames": 100} if "gpi_iteration_frames" in _c["ours"] else {})}

# the remaining cases of issue 29, not run yet (no runner written for their MB class)
PENDING = ["envelope-minecart", "gpi_ls-minecart", "pcn-dst", "pcn-fruit-tree", "capql-mountaincar",
           "gpi_ls-mountaincar (continuous)", "morld-mountaincar", "gpi_pd-dst", "capql-hopper", "pgmorl-hopper"]

# the shared evaluation protocol: MB's num_eval_weights_for_front; episodes 1 (these envs and the
# greedy policies are deterministic); the evaluation discount is the case's gamma
EVAL_WEIGHTS = 100
EVAL_EPISODES = 1


def evaluate_act(act, env_id: str, gamma: float, seed: int) -> dict[str, float]:
    """Evaluate ``act(obs [B, ...] np, w [B, k] np) -> actions [B]`` with morl_trl's evaluator:
    hypervolume (the env's reference point), EUM, IGD and the HV ratio to the true front."""
    import torch

    from morl_trl.evaluation import MultiContextEvaluator

    def policy(td):
        actions = act(td.get("observation").cpu().numpy(), td.get("preference").cpu().numpy())
        return td.set("action", torch.as_tensor(np.asarray(actions)))

    ev = MultiContextEvaluator(policy, env_id, weights=EVAL_WEIGHTS, episodes=EVAL_EPISODES, gamma=gamma, seed=seed)
    metrics = ev.evaluate().per_context[env_id].metrics
    ev.close()
    return {k: (None if v is None else float(v)) for k, v in metrics.items()}


def result_path(out: Path, case: str, lib: str, seed: int) -> Path:
    return Path(out) / case / f"{lib}_s{seed}.json"


def write_result(path: Path, data: dict) -> None:
    """Atomically: a crash never leaves a half-written result that a rerun would skip."""
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, suffix=".tmp")
    with os.fdopen(fd, "w") as fh:
        json.dump(data, fh, indent=1)
    os.replace(tmp, path)
