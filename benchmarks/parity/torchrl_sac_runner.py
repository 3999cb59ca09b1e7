"""The SAC baseline's reference in the parity benchmark: TorchRL's own SAC (``torchrl.objectives.SACLoss``)
trained in a plain loop in the style of TorchRL's ``sota-implementations/sac/sac.py`` (a ``Collector``,
torchrl 0.14's ``SyncDataCollector``, whose first ``init_random_frames`` are uniformly random, a ``TensorDictReplayBuffer``, one joint step of the
summed actor, critic and temperature losses per update, ``SoftUpdate`` after each), on the case's scalarized
task. Its results are the library ``torchrl_sac``. It runs in our Python, no MB venv:

    python torchrl_sac_runner.py CASE SEEDS OUT_DIR      # SEEDS: 100,101 ; the finished ones are skipped

Nothing of morl_trl trains here. The task is the env: our domain's Gymnasium id (``morl_trl/<id>``, registered by
``import morl_trl.gym``) under :class:`OriginalScalarReward`, which makes ``info["original_reward"]`` (the domain's
single-objective reward, SPEC §1) the reward, as the authors' ``Multi2SingleObjectiveWrapper`` gives their SAC
``info['original_scalar_reward']``; TorchRL's ``GymWrapper`` over it. The evaluation is the shared one
(``common.evaluate_policy``: morl_trl's evaluator on the same env id, weights, discount and seed as our runs),
at frame 0 and every ``eval_every`` frames; the actor's actions are sampled (the authors evaluate SAC
stochastically, SPEC §6), with the global RNG streams put back afterwards (``mb_runner.preserved_rng``) so that
evaluating leaves training as it would be. Training time is the loop's wall time minus the evaluations.

The case's ``ref`` gives the settings (the same values as ours' keys of the same names): ``hidden`` (ReLU MLPs:
actor ``obs -> hidden -> 2 |A|`` split into the mean and ``log_std = -5 + 3.5 (tanh(x) + 1)``, the authors'
and ours' parameterisation; critics ``[obs, a] -> hidden -> 1``), orthogonal init with zero biases on every
layer (the authors' ``layer_init``, what ours uses; each of SACLoss's two critic copies gets its own draw),
``batch_size``, ``init_random_frames``, ``lr`` (actor), ``q_lr`` (critics), ``alpha_lr`` (temperature),
``alpha`` (its initial value; tuned towards ``-|A|``, TorchRL's ``log_alpha`` form), ``tau`` (Polyak).
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

import numpy as np  # noqa: E402

from common import CASES, EVAL_EPISODES, evaluate_policy, result_path, write_result  # noqa: E402

LIB = "torchrl_sac"


def make_gym_env(env_id: str):
    """``morl_trl/<env_id>`` as a single-objective Gymnasium env: reward = ``info["original_reward"]``."""
    import gymnasium

    import morl_trl.gym  # noqa: F401  (registers the morl_trl/<id> Gymnasium ids: the task's env, not training)

    class OriginalScalarReward(gymnasium.Wrapper):
        """The domain's original scalar reward as the reward (the authors' Multi2SingleObjectiveWrapper)."""

        def __init__(self, env):
            super().__init__(env)
            # (read by TorchRL's GymWrapper for the reward spec: one scalar, not the vector's k)
            self.reward_space = gymnasium.spaces.Box(-np.inf, np.inf, shape=(1,), dtype=np.float32)

        def step(self, action):
            obs, _, terminated, truncated, info = self.env.step(action)
            return obs, np.float32(info["original_reward"]), terminated, truncated, info

    return OriginalScalarReward(gymnasium.make(f"morl_trl/{env_id}"))


def make_modules(env, hidden, device):
    """TorchRL's actor (``ProbabilisticActor`` with ``TanhNormal``) and critic (``ValueOperator``), as the sota
    script builds them, with the authors' log-std parameterisation and init."""
    import torch
    from tensordict.nn import InteractionType, TensorDictModule
    from torch import nn
    from torchrl.modules import MLP, ProbabilisticActor, ValueOperator
    from torchrl.modules.distributions import TanhNormal

    action_spec = env.action_spec_unbatched.to(device)
    act_dim = action_spec.shape[-1]

    class LocTanhLogStd(nn.Module):
        """``[..., 2 d] -> (loc, exp(-5 + 3.5 (tanh(x) + 1)))``: log-std in [-5, 2] (CleanRL's SAC)."""

        def forward(self, out):
            loc, x = out.chunk(2, -1)
            return loc, (-5.0 + 0.5 * (2.0 - -5.0) * (torch.tanh(x) + 1)).exp()

    actor_net = nn.Sequential(MLP(num_cells=list(hidden), out_features=2 * act_dim, activation_class=nn.ReLU,
                                  device=device), LocTanhLogStd())
    actor = ProbabilisticActor(
        module=TensorDictModule(actor_net, in_keys=["observation"], out_keys=["loc", "scale"]),
        in_keys=["loc", "scale"], spec=action_spec, distribution_class=TanhNormal,
        distribution_kwargs={"low": action_spec.space.low, "high": action_spec.space.high},
        default_interaction_type=InteractionType.RANDOM, return_log_prob=False)
    qvalue = ValueOperator(module=MLP(num_cells=list(hidden), out_features=1, activation_class=nn.ReLU, device=device),
                           in_keys=["observation", "action"])
    with torch.no_grad():  # (lazy layers materialised on a fake step, as the sota script does)
        td = env.fake_tensordict().to(device)
        actor(td)
        qvalue(td)
    for net in (actor, qvalue):
        orthogonal_(net)
    return actor, qvalue, action_spec


def orthogonal_(module):
    """Orthogonal weights (gain 1) and zero biases on every ``nn.Linear`` (the authors' ``layer_init``)."""
    import torch
    from torch import nn

    with torch.no_grad():
        for m in module.modules():
            if isinstance(m, nn.Linear):
                nn.init.orthogonal_(m.weight)
                nn.init.zeros_(m.bias)
    return module


def run(case_name: str, seed: int, out: Path) -> None:
    import copy

    import torch
    import torchrl
    from tensordict import TensorDict
    from torchrl.collectors import Collector
    from torchrl.data import LazyTensorStorage, TensorDictReplayBuffer
    from torchrl.envs import Compose, DoubleToFloat, GymWrapper, InitTracker, RewardSum, TransformedEnv
    from torchrl.envs.utils import ExplorationType, set_exploration_type
    from torchrl.objectives import SACLoss, SoftUpdate, group_optimizers

    from mb_runner import preserved_rng

    case = CASES[case_name]
    ref = case["ref"]
    device = torch.device("cpu")
    torch.set_num_threads(1)
    torch.manual_seed(seed)
    np.random.seed(seed)

    env = TransformedEnv(GymWrapper(make_gym_env(case["env"]), device=device),
                         Compose(InitTracker(), DoubleToFloat(), RewardSum()))
    env.set_seed(seed)
    actor, qvalue, action_spec = make_modules(env, ref["hidden"], device)

    loss = SACLoss(actor_network=actor, qvalue_network=qvalue, num_qvalue_nets=2, loss_function="l2",
                   delay_actor=False, delay_qvalue=True, alpha_init=ref["alpha"], action_spec=action_spec)
    with torch.no_grad():  # each critic copy its own orthogonal draw, the target the same values
        params = loss.qvalue_network_params.data
        for i in range(params.batch_size[0]):
            params[i].update_(TensorDict.from_module(orthogonal_(copy.deepcopy(qvalue))).data)
        loss.target_qvalue_network_params.data.update_(params)
    loss.make_value_estimator(gamma=case["gamma"])
    target_updater = SoftUpdate(loss, tau=ref["tau"])
    optimizer = group_optimizers(
        torch.optim.Adam(list(loss.actor_network_params.flatten_keys().values()), lr=ref["lr"]),
        torch.optim.Adam(list(loss.qvalue_network_params.flatten_keys().values()), lr=ref["q_lr"]),
        torch.optim.Adam([loss.log_alpha], lr=ref["alpha_lr"]))

    buffer = TensorDictReplayBuffer(storage=LazyTensorStorage(case["frames"]), batch_size=ref["batch_size"])
    collector = Collector(env, actor, frames_per_batch=1, total_frames=case["frames"],
                                  init_random_frames=ref["init_random_frames"], device=device)
    collector.set_seed(seed)

    curve: list[dict] = []
    eval_s, eval_cpu = [0.0], [0.0]

    def policy(td):  # the evaluator's TensorDict: observation (and a preference SAC ignores) in, action out
        with set_exploration_type(ExplorationType.RANDOM), torch.no_grad():
            return td.set("action", actor(td.select("observation").clone())["action"])

    def evaluate(frames: int) -> None:
        t, c = time.perf_counter(), time.process_time()
        with preserved_rng():
            m = evaluate_policy(policy, case["env"], case["gamma"], seed)
        curve.append(dict(frames=frames, **m))
        eval_s[0] += time.perf_counter() - t
        eval_cpu[0] += time.process_time() - c
        print(f"[{LIB} {case_name} s{seed}] {frames} frames: {m}", flush=True)

    def update(batch):  # the sota script's update: one step of the summed losses, then the target step
        out = loss(batch)
        (out["loss_actor"] + out["loss_qvalue"] + out["loss_alpha"]).sum().backward()
        optimizer.step()
        optimizer.zero_grad(set_to_none=True)
        target_updater.step()
        return out.detach()

    evaluate(0)
    t0, e0, frames, updates = time.perf_counter(), eval_s[0], 0, 0
    c0, ec0 = time.process_time(), eval_cpu[0]
    for batch in collector:
        collector.update_policy_weights_()
        buffer.extend(batch.reshape(-1))
        frames += batch.numel()
        if frames >= ref["init_random_frames"]:
            for _ in range(batch.numel()):  # utd 1
                update(buffer.sample())
                updates += 1
        if frames % case["eval_every"] == 0:
            evaluate(frames)
    collector.shutdown()
    train_s = time.perf_counter() - t0 - (eval_s[0] - e0)
    train_cpu = time.process_time() - c0 - (eval_cpu[0] - ec0)  # (this process's CPU time: one torch thread)
    write_result(out, dict(case=case_name, lib=LIB, seed=seed, version=f"torchrl {torchrl.__version__} SACLoss",
                           curve=curve, frames=frames, updates=updates, train_seconds=train_s,
                           eval_seconds=eval_s[0], train_fps=frames / train_s if train_s > 0 else None,
                           train_cpu_seconds=train_cpu, train_fps_cpu=frames / train_cpu if train_cpu > 0 else None,
                           eval_episodes=EVAL_EPISODES))


if __name__ == "__main__":  # several seeds in one process: the imports are paid once
    for _seed in [int(x) for x in sys.argv[2].split(",")]:
        _path = result_path(Path(sys.argv[3]), sys.argv[1], LIB, _seed)
        if not _path.exists():
            run(sys.argv[1], _seed, _path)
