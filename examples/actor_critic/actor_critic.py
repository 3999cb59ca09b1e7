"""CAPQL (Lu, Herman & Yu, ICLR 2023) or MOSAC (multi-objective SAC, MORL/D's building block)
trained as a generalist on a MuJoCo domain under domain randomization, with the paper's
state-action history.

The paper's loop (§6) written out top to bottom; ``morl-trl train capql|mosac ENV_ID`` runs
the same recipe with checkpoints, resume, logging and a report.

    python examples/actor_critic/actor_critic.py --algo capql     # MO-Hopper, quick preset
    python examples/actor_critic/actor_critic.py --algo mosac --config examples/actor_critic/half_cheetah_quick.toml
    python examples/actor_critic/actor_critic.py --algo capql --config examples/actor_critic/hopper_paper.toml
"""

import argparse
from pathlib import Path

import torch
from torchrl.collectors import Collector
from torchrl.data import LazyTensorStorage, TensorDictReplayBuffer
from torchrl.envs.utils import ExplorationType
from torchrl.objectives import SoftUpdate

from morl_trl.evaluation import MultiContextEvaluator, domain_env_factory
from morl_trl.envs import domain_of
from morl_trl.objectives import CAPQLLoss, MOSACLoss, make_gaussian_actor, make_vector_critic
from morl_trl.trainers import resolve_config
from morl_trl.trainers.env_factory import make_eval_transform, make_train_env

parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
parser.add_argument("--algo", choices=("capql", "mosac"), default="capql")
parser.add_argument("--config", default=str(Path(__file__).with_name("hopper_quick.toml")))
parser.add_argument("--seed", type=int, default=0)
args = parser.parse_args()

# ---------------------------------------------------------------- config: paper defaults + file
cfg = resolve_config(args.algo, "MOHopperDR-v5", config_file=args.config, seed=args.seed)
torch.manual_seed(cfg.seed)
torch.set_num_threads(cfg.num_threads)
spec = domain_of(cfg.env_id)
gamma = cfg.gamma if cfg.gamma is not None else spec.gamma

# ---------------------------------------------------------------- environment: DR + history + preferences
env = make_train_env(cfg, torch.device(cfg.device))
obs_dim = env.observation_spec["observation"].shape[-1]          # 39 for MO-Hopper with history 2
action_spec = env.action_spec[0]

# ---------------------------------------------------------------- networks: pi(a | s, w), two vector critics Q(s, a, w)
actor = make_gaussian_actor(obs_dim, action_spec, spec.num_objectives, num_cells=cfg.hidden)
critic = make_vector_critic(obs_dim, action_spec.shape[-1], spec.num_objectives, num_cells=cfg.hidden)

# ---------------------------------------------------------------- loss, optimizers, target critics
if args.algo == "capql":  # fresh preferences per sample, per-objective min of the critics, fixed alpha
    loss = CAPQLLoss(actor, critic, alpha=cfg.alpha)
else:  # the episode's preference from the batch, scalarized critic min, learned temperature
    loss = MOSACLoss(actor, critic, alpha_init=cfg.alpha, fixed_alpha=not cfg.learn_alpha, action_spec=action_spec)
loss.make_value_estimator(gamma=gamma)
params = {"actor": loss.actor_network_params, "qvalue": loss.qvalue_network_params}
optims = {name: torch.optim.Adam(p.values(True, True), lr=cfg.lr) for name, p in params.items()}
if isinstance(loss.log_alpha, torch.nn.Parameter):
    optims["alpha"] = torch.optim.Adam([loss.log_alpha], lr=cfg.lr)
target = SoftUpdate(loss, tau=cfg.tau)

# ---------------------------------------------------------------- data
collector = Collector(env, actor, frames_per_batch=cfg.frames_per_batch, total_frames=cfg.frames,
                      init_random_frames=cfg.init_random_frames, exploration_type=ExplorationType.RANDOM,
                      auto_register_policy_transforms=False)
buffer = TensorDictReplayBuffer(storage=LazyTensorStorage(cfg.buffer_size), batch_size=cfg.batch_size)
evaluator = MultiContextEvaluator(actor, spec.train_id, weights=cfg.eval_weights, gamma=gamma,
                                  env_factory=domain_env_factory(spec.train_id, make_eval_transform(cfg)), seed=cfg.seed)

# ---------------------------------------------------------------- the loop
frames, next_eval = 0, cfg.eval_interval
for batch in collector:
    buffer.extend(batch.reshape(-1))
    frames += batch.numel()
    if frames >= cfg.init_random_frames:
        for _ in range(cfg.updates_per_batch or cfg.frames_per_batch):
            out = loss(buffer.sample())
            for opt in optims.values():
                opt.zero_grad()
            sum(v for k, v in out.items() if k.startswith("loss_")).backward()
            for opt in optims.values():
                opt.step()
            target.step()
    collector.update_policy_weights_()
    if frames >= next_eval or frames >= cfg.frames:
        next_eval += cfg.eval_interval
        result = evaluator.evaluate()
        hv = ", ".join(f"{c.split('-')[0][len(spec.name) - 1:]}={v:.3g}" for c, v in result.metric("hypervolume").items())
        print(f"frames {frames:>8}  critic loss {out['loss_qvalue'].item():.3f}  hypervolume: {hv}", flush=True)
collector.shutdown()
