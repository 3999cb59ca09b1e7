"""MOSAC (multi-objective SAC with vector critics, the building block of MORL/D) trained as a generalist on a MuJoCo domain under domain
randomization, with the paper's state-action history.

The paper's loop (§6) written out top to bottom; ``morl-trl train mosac ENV_ID`` runs the
same recipe with checkpoints, resume, logging and a report.

    python examples/mosac/mosac.py                                # MO-HalfCheetah, quick preset
    python examples/mosac/mosac.py --config examples/mosac/half_cheetah_paper.toml
"""

import argparse
from pathlib import Path

import torch
from torchrl.collectors import Collector
from torchrl.data import LazyTensorStorage, TensorDictReplayBuffer
from torchrl.envs.utils import ExplorationType
from torchrl.objectives import SoftUpdate

from morl_trl.collectors import MultiContextEvaluator
from morl_trl.envs import domain_of
from morl_trl.objectives import MOSACLoss, make_gaussian_actor, make_vector_critic
from morl_trl.trainers import resolve_config
from morl_trl.trainers.env_factory import make_eval_transform, make_train_env

parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
parser.add_argument("--config", default=str(Path(__file__).with_name("half_cheetah_quick.toml")))
parser.add_argument("--seed", type=int, default=0)
args = parser.parse_args()

# ---------------------------------------------------------------- config: paper defaults + file
cfg = resolve_config("mosac", "MOHalfCheetahDR-v5", config_file=args.config, seed=args.seed)
torch.manual_seed(cfg.seed)
spec = domain_of(cfg.env_id)
gamma = cfg.gamma if cfg.gamma is not None else spec.gamma

# ---------------------------------------------------------------- environment: DR + history + preferences
env = make_train_env(cfg, torch.device(cfg.device))
obs_dim = env.observation_spec["observation"].shape[-1]          # 63 for MO-HalfCheetah with history 2
action_spec = env.action_spec[0]

# ---------------------------------------------------------------- networks: pi(a | s, w), two vector critics Q(s, a, w)
actor = make_gaussian_actor(obs_dim, action_spec, spec.num_objectives, num_cells=cfg.hidden)
critic = make_vector_critic(obs_dim, action_spec.shape[-1], spec.num_objectives, num_cells=cfg.hidden)

# ---------------------------------------------------------------- loss (the episode's preference from the batch), learned temperature
loss = MOSACLoss(actor, critic, alpha_init=cfg.alpha, fixed_alpha=not cfg.learn_alpha, action_spec=action_spec)
loss.make_value_estimator(gamma=gamma)
actor_opt = torch.optim.Adam(loss.actor_network_params.values(True, True), lr=cfg.lr)
critic_opt = torch.optim.Adam(loss.qvalue_network_params.values(True, True), lr=cfg.lr)
alpha_opt = torch.optim.Adam([loss.log_alpha], lr=cfg.lr) if cfg.learn_alpha else None
target = SoftUpdate(loss, tau=cfg.tau)

# ---------------------------------------------------------------- data
collector = Collector(env, actor, frames_per_batch=cfg.frames_per_batch, total_frames=cfg.frames,
                      init_random_frames=cfg.init_random_frames, exploration_type=ExplorationType.RANDOM,
                      auto_register_policy_transforms=False)
buffer = TensorDictReplayBuffer(storage=LazyTensorStorage(cfg.buffer_size), batch_size=cfg.batch_size)
evaluator = MultiContextEvaluator(actor, spec.train_id, weights=cfg.eval_weights, gamma=gamma,
                                  transform=make_eval_transform(cfg), seed=cfg.seed)

# ---------------------------------------------------------------- the loop
frames, next_eval = 0, cfg.eval_interval
for batch in collector:
    buffer.extend(batch.reshape(-1))
    frames += batch.numel()
    if frames >= cfg.init_random_frames:
        for _ in range(cfg.updates_per_batch or cfg.frames_per_batch):
            out = loss(buffer.sample())
            actor_opt.zero_grad()
            critic_opt.zero_grad()
            total = out["loss_actor"] + out["loss_qvalue"]
            if alpha_opt is not None:
                alpha_opt.zero_grad()
                total = total + out["loss_alpha"]
            total.backward()
            actor_opt.step()
            critic_opt.step()
            if alpha_opt is not None:
                alpha_opt.step()
            target.step()
    collector.update_policy_weights_()
    if frames >= next_eval or frames >= cfg.frames:
        next_eval += cfg.eval_interval
        result = evaluator.evaluate()
        hv = ", ".join(f"{c.replace('MOHalfCheetah', '')[:-3]}={v:.3g}" for c, v in result.metric("hypervolume").items())
        print(f"frames {frames:>8}  critic {out['loss_qvalue'].item():.3f}  hypervolume: {hv}", flush=True)
collector.shutdown()
