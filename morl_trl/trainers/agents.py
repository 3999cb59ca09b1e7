"""Algorithm-specific pieces of a run: networks, policies, loss, optimizers, target updates.

An :class:`Agent` is what :func:`~morl_trl.trainers.loop.train` drives; :func:`build_agent`
makes the one a :class:`~morl_trl.trainers.config.TrainConfig` names:

=================  ===========================================  ==========================
algo               loss                                         actions
=================  ===========================================  ==========================
``envelope``       :class:`~morl_trl.objectives.EnvelopeQLoss`  discrete, epsilon-greedy
``capql``          :class:`~morl_trl.objectives.CAPQLLoss`      continuous, tanh-Gaussian
``mosac``          :class:`~morl_trl.objectives.MOSACLoss`      continuous, tanh-Gaussian
``mosac_discrete`` :class:`~morl_trl.objectives.DiscreteMOSACLoss` discrete, categorical
=================  ===========================================  ==========================
"""

from __future__ import annotations

import math

import torch
from tensordict import TensorDictBase
from tensordict.nn import TensorDictModule, TensorDictSequential
from torch import nn
from torchrl.collectors import Collector
from torchrl.data import Categorical, LazyTensorStorage, OneHot, TensorDictReplayBuffer
from torchrl.envs.utils import ExplorationType
from torchrl.modules import EGreedyModule
from torchrl.objectives import HardUpdate, SoftUpdate

__all__ = ["Agent", "build_agent", "NonFiniteLossError", "ScalarizedArgmax"]


class NonFiniteLossError(RuntimeError):
    """A loss came out NaN or infinite; the update was not applied."""


class ScalarizedArgmax(nn.Module):
    """``argmax_a w · Q(s, a, w)``: the greedy action of a vector Q-network for preference ``w``.

    Example:
        >>> q = torch.tensor([[[1.0, 0.0], [0.0, 1.0]]])   # [B=1, |A|=2, k=2]
        >>> ScalarizedArgmax()(q, torch.tensor([[0.2, 0.8]]))
        tensor([1])
    """

    def forward(self, action_value: torch.Tensor, preference: torch.Tensor) -> torch.Tensor:
        return (action_value * preference.unsqueeze(-2)).sum(-1).argmax(-1)


class Agent:
    """Holds the modules of one algorithm and performs its updates.

    Attributes:
        explore_policy: acts during collection (epsilon-greedy / stochastic).
        eval_policy: acts during evaluation (greedy / mean action unless ``eval_stochastic``).
        loss: the :class:`~torchrl.objectives.LossModule`.
        optimizers: name -> optimizer; stepped together after one backward of the summed losses.
        target_updater: TorchRL ``SoftUpdate`` / ``HardUpdate`` (stepped after every update).
    """

    def __init__(self, cfg, loss, explore_policy, eval_policy, optimizers, target_updater,
                 *, device, exploration_module=None, eval_exploration=ExplorationType.DETERMINISTIC) -> None:
        self.cfg = cfg
        self.loss = loss
        self.explore_policy = explore_policy
        self.eval_policy = eval_policy
        self.optimizers = optimizers
        self.target_updater = target_updater
        self.device = device
        self.exploration_module = exploration_module
        self.eval_exploration = eval_exploration
        self.loss_keys = [k for k in loss.out_keys if k.startswith("loss_")]

    # ------------------------------------------------------------------ data
    def make_replay_buffer(self) -> TensorDictReplayBuffer:
        cfg = self.cfg
        storage = LazyTensorStorage(cfg.buffer_size, device=self.device)
        if cfg.prioritized:
            from morl_trl.data import prioritized_sampler

            sampler = prioritized_sampler(cfg.buffer_size, alpha=cfg.per_alpha, beta=cfg.per_beta, device=self.device)
            return TensorDictReplayBuffer(storage=storage, sampler=sampler, batch_size=cfg.batch_size,
                                          priority_key="td_error")
        return TensorDictReplayBuffer(storage=storage, batch_size=cfg.batch_size)

    def make_collector(self, env, *, total_frames: int, frames_done: int = 0) -> Collector:
        cfg = self.cfg
        per_batch = cfg.frames_per_batch

        def whole_batches(frames: int) -> int:  # the collector works in whole batches anyway
            return -(-max(frames, 0) // per_batch) * per_batch

        return Collector(
            env,
            self.explore_policy,
            frames_per_batch=per_batch,
            total_frames=max(whole_batches(total_frames), per_batch),
            init_random_frames=whole_batches(cfg.init_random_frames - frames_done),
            device=self.device,
            exploration_type=ExplorationType.RANDOM,
            auto_register_policy_transforms=False,  # our policies are feed-forward: no InitTracker needed
        )

    def make_evaluator(self, transform, spec):
        from morl_trl.evaluation import MultiContextEvaluator, domain_env_factory

        cfg = self.cfg
        reference = None
        if cfg.reference_dir:
            from morl_trl.reporting.reference import load_domain_reference

            reference = load_domain_reference(cfg.reference_dir, spec.train_id)
        self.reference = reference
        evaluator = MultiContextEvaluator(
            self.eval_policy,
            list(cfg.eval_contexts) if cfg.eval_contexts else spec.train_id,
            weights=cfg.eval_weights,
            episodes=cfg.eval_episodes,
            gamma=cfg.gamma if cfg.gamma is not None else spec.gamma,
            env_factory=domain_env_factory(spec.train_id, transform, device=self.device),
            reference=reference,
            exploration_type=self.eval_exploration,
            device=self.device,
            seed=cfg.seed,
        )
        return lambda policy: evaluator.evaluate(policy)

    # ------------------------------------------------------------------ learning
    def update(self, buffer) -> TensorDictBase:
        """One gradient step on a sampled batch; raises :class:`NonFiniteLossError` before stepping on NaNs."""
        batch = buffer.sample().to(self.device)
        out = self.loss(batch)
        total = sum(out[k] for k in self.loss_keys)
        if not torch.isfinite(total):
            bad = {k: out[k].item() for k in self.loss_keys}
            raise NonFiniteLossError(f"non-finite loss {bad}; the networks were left as they were before this update")
        for opt in self.optimizers.values():
            opt.zero_grad(set_to_none=True)
        total.backward()
        for opt in self.optimizers.values():
            opt.step()
        self.target_updater.step()
        if self.cfg.prioritized:
            buffer.update_tensordict_priority(batch)
        return out.detach()

    def on_frames(self, frames: int) -> None:
        """Advance the frame-based schedules (epsilon, homotopy)."""
        if self.exploration_module is not None:
            self.exploration_module.eps.fill_(self._eps(frames))
        if hasattr(self.loss, "update_homotopy"):
            self.loss.update_homotopy(frames)

    def _eps(self, frames: int) -> float:
        cfg = self.cfg
        frac = min(1.0, frames / max(1, cfg.eps_frames))
        return cfg.eps_start + frac * (cfg.eps_end - cfg.eps_start)

    # ------------------------------------------------------------------ state
    def state_dict(self) -> dict:
        return {
            "loss": self.loss.state_dict(),
            "optimizers": {k: o.state_dict() for k, o in self.optimizers.items()},
            "target_updater_counter": getattr(self.target_updater, "counter", None),  # HardUpdate's period
        }

    def load_state_dict(self, state: dict) -> None:
        self.loss.load_state_dict(state["loss"])
        for k, o in self.optimizers.items():
            o.load_state_dict(state["optimizers"][k])
        if state.get("target_updater_counter") is not None and hasattr(self.target_updater, "counter"):
            self.target_updater.counter = state["target_updater_counter"]


# ---------------------------------------------------------------------- builders
def _obs_shape(env) -> tuple[int, ...]:
    return tuple(env.observation_spec["observation"].shape[len(env.batch_size):])


def _num_objectives(env) -> int:
    return int(env.full_reward_spec[env.reward_key].shape[-1])


def _action_spec(env):
    spec = env.full_action_spec[env.action_key]
    return spec[(0,) * len(env.batch_size)] if len(env.batch_size) else spec


def _target_updater(cfg, loss):
    if cfg.tau is not None:
        return SoftUpdate(loss, tau=cfg.tau)
    return HardUpdate(loss, value_network_update_interval=cfg.target_update_period)


def _build_envelope(cfg, env, gamma, device) -> Agent:
    from morl_trl.objectives import EnvelopeQLoss, make_vector_q_network

    spec = _action_spec(env)
    if not isinstance(spec, (Categorical, OneHot)):
        raise ValueError(f"envelope needs discrete actions; {cfg.env_id} has {type(spec).__name__}: use capql or mosac")
    k = _num_objectives(env)
    q = make_vector_q_network(_obs_shape(env), spec.space.n, k, num_cells=cfg.hidden).to(device)
    greedy = TensorDictSequential(q, TensorDictModule(ScalarizedArgmax(), ["action_value", "preference"], ["action"]))
    egreedy = EGreedyModule(env.full_action_spec, eps_init=cfg.eps_start, eps_end=cfg.eps_end,
                            annealing_num_steps=max(1, cfg.eps_frames))
    explore = TensorDictSequential(greedy, egreedy)
    loss = EnvelopeQLoss(
        q, num_preference_samples=cfg.num_sampled_prefs, homotopy_lambda=cfg.homotopy_lambda0,
        final_homotopy_lambda=1.0, homotopy_steps=cfg.homotopy_frames or cfg.frames,
    )
    loss.make_value_estimator(gamma=gamma)
    opt = {"qvalue": torch.optim.Adam(loss.parameters(), lr=cfg.lr)}
    return Agent(cfg, loss, explore, greedy, opt, _target_updater(cfg, loss), device=device,
                 exploration_module=egreedy)


def _actor_critic_optimizers(cfg, loss) -> dict:
    opts = {
        "actor": torch.optim.Adam(loss.actor_network_params.values(True, True), lr=cfg.lr),
        "qvalue": torch.optim.Adam(loss.qvalue_network_params.values(True, True), lr=cfg.lr),
    }
    if isinstance(getattr(loss, "log_alpha", None), nn.Parameter):
        opts["alpha"] = torch.optim.Adam([loss.log_alpha], lr=cfg.lr)
    return opts


def _build_continuous(cfg, env, gamma, device, capql: bool) -> Agent:
    from morl_trl.objectives import CAPQLLoss, MOSACLoss, make_gaussian_actor, make_vector_critic

    spec = _action_spec(env)
    if isinstance(spec, (Categorical, OneHot)):
        raise ValueError(f"{cfg.algo} needs continuous actions; {cfg.env_id} is discrete: use envelope or mosac_discrete")
    (obs_dim,) = _obs_shape(env)
    k = _num_objectives(env)
    actor = make_gaussian_actor(obs_dim, spec.to(device), k, num_cells=cfg.hidden).to(device)
    critic = make_vector_critic(obs_dim, spec.shape[-1], k, num_cells=cfg.hidden).to(device)
    if capql:
        loss = CAPQLLoss(actor, critic, alpha=cfg.alpha)
    else:
        loss = MOSACLoss(actor, critic, alpha_init=cfg.alpha, fixed_alpha=not cfg.learn_alpha, action_spec=spec)
    loss.make_value_estimator(gamma=gamma)
    return Agent(cfg, loss, actor, actor, _actor_critic_optimizers(cfg, loss), _target_updater(cfg, loss),
                 device=device)


def _build_mosac_discrete(cfg, env, gamma, device) -> Agent:
    from morl_trl.objectives import DiscreteMOSACLoss, make_categorical_actor, make_vector_q_network

    spec = _action_spec(env)
    if not isinstance(spec, (Categorical, OneHot)):
        raise ValueError(f"mosac_discrete needs discrete actions; {cfg.env_id} is continuous: use mosac or capql")
    n, k, obs = spec.space.n, _num_objectives(env), _obs_shape(env)
    actor = make_categorical_actor(obs, n, k, num_cells=cfg.hidden, action_spec=spec).to(device)
    critic = make_vector_q_network(obs, n, k, num_cells=cfg.hidden).to(device)
    target_entropy = cfg.target_entropy_scale * math.log(n)
    loss = DiscreteMOSACLoss(actor, critic, num_actions=n, alpha_init=cfg.alpha, fixed_alpha=not cfg.learn_alpha,
                             target_entropy=target_entropy)
    loss.make_value_estimator(gamma=gamma)
    return Agent(cfg, loss, actor, actor, _actor_critic_optimizers(cfg, loss), _target_updater(cfg, loss),
                 device=device, eval_exploration=ExplorationType.RANDOM)


def build_agent(cfg, env, *, gamma: float, device) -> Agent:
    """The :class:`Agent` of ``cfg.algo`` for ``env`` (a batched env with ``"preference"``)."""
    if cfg.algo == "envelope":
        return _build_envelope(cfg, env, gamma, device)
    if cfg.algo in ("capql", "mosac"):
        return _build_continuous(cfg, env, gamma, device, capql=cfg.algo == "capql")
    if cfg.algo == "mosac_discrete":
        return _build_mosac_discrete(cfg, env, gamma, device)
    from morl_trl.trainers.config import ALGORITHMS

    raise ValueError(f"unknown algorithm {cfg.algo!r}; valid: {list(ALGORITHMS)}")
