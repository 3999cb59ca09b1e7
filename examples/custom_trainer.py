"""Your own training loop from morl_trl's public pieces: Envelope on MO-LavaGrid under domain randomization.

This is not the recipe that ``morl-trl train`` runs (that is ``morl_trl/algorithms/envelope/recipe.py``,
the same loop inside ``Run.session``: checkpoints, resume, logs and a report); it shows
what a custom trainer composes: a DR env, the policy/training stacks, a vector Q-network with
its scalarized greedy policy, the Envelope loss, TorchRL's collector and replay buffer, and
the multi-context evaluator on the same policy stack.

    python examples/custom_trainer.py --frames 20000
"""

import argparse

import torch
from tensordict.nn import TensorDictSequential
from torchrl.collectors import Collector
from torchrl.data import LazyTensorStorage, TensorDictReplayBuffer
from torchrl.modules import EGreedyModule
from torchrl.objectives import HardUpdate

from morl_trl.envs import domain_of, make_env
from morl_trl.evaluation import MultiContextEvaluator
from morl_trl.objectives import EnvelopeQLoss, MOQValueModule, make_vector_q_network
from morl_trl.transforms import compose_policy_env, compose_training_env

parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
parser.add_argument("--env-id", default="MOLavaGridDR-v0")
parser.add_argument("--frames", type=int, default=20_000)
parser.add_argument("--eval-weights", type=int, default=8)
parser.add_argument("--seed", type=int, default=0)
args = parser.parse_args()
torch.manual_seed(args.seed)
spec = domain_of(args.env_id)

env = compose_training_env(make_env(args.env_id, num_envs=16, seed=args.seed), gamma=spec.gamma,
                           history_len=spec.history_len, preference_seed=args.seed + 1)
qnet = make_vector_q_network(env.observation_spec["observation"].shape[1:], env.action_spec.space.n,
                             spec.num_objectives, num_cells=(128, 128))
greedy = TensorDictSequential(qnet, MOQValueModule())                  # argmax_a w . Q(s, a, w)
explore = TensorDictSequential(greedy, EGreedyModule(env.full_action_spec, annealing_num_steps=args.frames // 2))
loss = EnvelopeQLoss(qnet, num_preference_samples=8)
loss.make_value_estimator(gamma=spec.gamma)
optim = torch.optim.Adam(loss.parameters(), lr=3e-4)
target = HardUpdate(loss, value_network_update_interval=250)
buffer = TensorDictReplayBuffer(storage=LazyTensorStorage(100_000), batch_size=128)
collector = Collector(env, explore, frames_per_batch=64, total_frames=args.frames, init_random_frames=1_000)
evaluator = MultiContextEvaluator(
    greedy, args.env_id, weights=args.eval_weights, seed=args.seed,
    env_factory=lambda num_envs, seed: compose_policy_env(make_env(args.env_id, num_envs=num_envs, seed=seed),
                                                           history_len=spec.history_len))

frames = 0
for batch in collector:
    buffer.extend(batch.reshape(-1))
    frames += batch.numel()
    if frames >= 1_000:
        for _ in range(16):
            loss_td = loss(buffer.sample())
            optim.zero_grad()
            loss_td["loss_qvalue"].backward()
            optim.step()
            target.step()
    explore[-1].step(batch.numel())
collector.shutdown()
result = evaluator.evaluate()
print(f"frames {frames}: hypervolume per context " +
      ", ".join(f"{c.removeprefix('MOLavaGrid').removesuffix('-v0')}={v:.4g}" for c, v in result.metric("hypervolume").items()))
