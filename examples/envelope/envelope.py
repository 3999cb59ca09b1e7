"""Envelope Q-learning (Yang et al., 2019) trained as a generalist under domain randomization.

The paper's experimental loop (§6) written out top to bottom with morl_trl's and TorchRL's
pieces; ``morl-trl train envelope ENV_ID`` runs the same recipe with checkpoints, resume,
CSV/TensorBoard logging and a report.

    python examples/envelope/envelope.py                          # MO-LunarLander, quick preset
    python examples/envelope/envelope.py --config examples/envelope/lava_grid_quick.toml
    python examples/envelope/envelope.py --config examples/envelope/lunar_lander_paper.toml
"""

import argparse
from pathlib import Path

import torch
from tensordict.nn import TensorDictModule, TensorDictSequential
from torchrl.collectors import Collector
from torchrl.data import LazyTensorStorage, TensorDictReplayBuffer
from torchrl.envs.utils import ExplorationType
from torchrl.modules import EGreedyModule
from torchrl.objectives import HardUpdate

from morl_trl.evaluation import MultiContextEvaluator, domain_env_factory
from morl_trl.data import prioritized_sampler
from morl_trl.envs import domain_of
from morl_trl.objectives import EnvelopeQLoss, make_vector_q_network
from morl_trl.trainers import resolve_config
from morl_trl.trainers.agents import ScalarizedArgmax
from morl_trl.trainers.env_factory import make_eval_transform, make_train_env

parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
parser.add_argument("--config", default=str(Path(__file__).with_name("lunar_lander_quick.toml")))
parser.add_argument("--seed", type=int, default=0)
args = parser.parse_args()

# ---------------------------------------------------------------- config: paper defaults + file
cfg = resolve_config("envelope", "MOLunarLanderDR-v0", config_file=args.config, seed=args.seed)
torch.manual_seed(cfg.seed)
torch.set_num_threads(cfg.num_threads)
spec = domain_of(cfg.env_id)
gamma = cfg.gamma if cfg.gamma is not None else spec.gamma

# ---------------------------------------------------------------- environment: DR + history + preferences
env = make_train_env(cfg, torch.device(cfg.device))  # make_env + StateActionHistory + PreferenceConditioning
obs_shape = env.observation_spec["observation"].shape[1:]
num_actions = env.action_spec.space.n

# ---------------------------------------------------------------- networks and policies
qnet = make_vector_q_network(obs_shape, num_actions, spec.num_objectives, num_cells=cfg.hidden)  # Q(s, ., w): [|A|, k]
greedy = TensorDictSequential(qnet, TensorDictModule(ScalarizedArgmax(), ["action_value", "preference"], ["action"]))
egreedy = EGreedyModule(env.full_action_spec, eps_init=cfg.eps_start, eps_end=cfg.eps_end,
                        annealing_num_steps=cfg.eps_frames)
explore = TensorDictSequential(greedy, egreedy)

# ---------------------------------------------------------------- loss, optimizer, target network
loss = EnvelopeQLoss(qnet, num_preference_samples=cfg.num_sampled_prefs, homotopy_lambda=cfg.homotopy_lambda0,
                     final_homotopy_lambda=1.0, homotopy_steps=cfg.frames)
loss.make_value_estimator(gamma=gamma)
optim = torch.optim.Adam(loss.parameters(), lr=cfg.lr)
target = HardUpdate(loss, value_network_update_interval=cfg.target_update_period)

# ---------------------------------------------------------------- data
collector = Collector(env, explore, frames_per_batch=cfg.frames_per_batch, total_frames=cfg.frames,
                      init_random_frames=cfg.init_random_frames, exploration_type=ExplorationType.RANDOM,
                      auto_register_policy_transforms=False)
buffer = TensorDictReplayBuffer(
    storage=LazyTensorStorage(cfg.buffer_size),
    sampler=prioritized_sampler(cfg.buffer_size, alpha=cfg.per_alpha, beta=cfg.per_beta),
    batch_size=cfg.batch_size, priority_key="td_error",
)
evaluator = MultiContextEvaluator(greedy, spec.train_id, weights=cfg.eval_weights, gamma=gamma,
                                  env_factory=domain_env_factory(spec.train_id, make_eval_transform(cfg)), seed=cfg.seed)

# ---------------------------------------------------------------- the loop
frames, next_eval = 0, cfg.eval_interval
for batch in collector:
    buffer.extend(batch.reshape(-1))
    frames += batch.numel()
    if frames >= cfg.init_random_frames:
        for _ in range(cfg.updates_per_batch or cfg.frames_per_batch):
            sample = buffer.sample()
            loss_td = loss(sample)
            optim.zero_grad()
            loss_td["loss_qvalue"].backward()
            optim.step()
            target.step()
            buffer.update_tensordict_priority(sample)
    egreedy.step(batch.numel())
    loss.update_homotopy(frames)
    collector.update_policy_weights_()
    if frames >= next_eval or frames >= cfg.frames:
        next_eval += cfg.eval_interval
        result = evaluator.evaluate()
        hv = ", ".join(f"{c.split('-')[0][len(spec.name) - 1:]}={v:.3g}" for c, v in result.metric("hypervolume").items())
        print(f"frames {frames:>8}  loss {loss_td['loss_qvalue'].item():.3f}  hypervolume: {hv}", flush=True)
collector.shutdown()
