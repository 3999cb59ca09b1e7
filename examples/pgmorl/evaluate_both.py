"""Evaluate a PGMORL run's last checkpoint both ways: as the authors (raw observations fed to the
normalised policies, SPEC §5 12) and corrected (the training normalisation applied, frozen).

    python examples/pgmorl/evaluate_both.py runs/<pgmorl run>
"""

import sys

import torch

from morl_trl.recipes import TrainConfig
from morl_trl.recipes.off_policy import build
from morl_trl.runs.checkpoint import find_checkpoint, load_checkpoint

run = sys.argv[1]
cfg = TrainConfig.load(f"{run}/config.json")
ckpt, _ = find_checkpoint(run)
for mode in ("raw", "normalized"):
    cfg.pgmorl_eval_obs = mode
    torch.manual_seed(cfg.seed)
    _, agent, _, evaluator = build(cfg, torch.device(cfg.device))
    agent.load_state_dict(load_checkpoint(ckpt)["agent"])
    nhgr = evaluator.evaluate().metric("nhgr")
    print(f"pgmorl_eval_obs={mode}: NHGR mean over contexts {sum(nhgr.values()) / len(nhgr):.4f}")
