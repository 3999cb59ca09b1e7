"""The :class:`Agent` (an algorithm's loss, policies, optimizers, target updater and state) and the
pieces every agent builder shares.

The builders, updates and loops live with their algorithm (:mod:`morl_trl.algorithms.envelope.recipe`,
:mod:`morl_trl.algorithms.actor_critic.recipe`, ...); :func:`morl_trl.recipes.build_agent` picks one by name.
"""

from __future__ import annotations

import contextlib
import copy

import torch
from tensordict import TensorDict, TensorDictBase
from torch import nn
from torchrl.data import Categorical, OneHot
from torchrl.envs.utils import ExplorationType
from torchrl.modules import EGreedyModule

from morl_trl.data.lean import extend_selected
from morl_trl.objectives import PolyakUpdate
from morl_trl.objectives.networks import orthogonal_init_
from morl_trl.objectives.updaters import PeriodicHardUpdate
from morl_trl.training.optim import NonFiniteLossError, adam, fused_choice, keep_implementation
from morl_trl.training.state_upgrade import upgrade_agent_state

__all__ = ["Agent", "NonFiniteLossError", "counted_update", "updates_due", "captures", "runs_captured",
           "captured_update",
           "adam", "fused_choice", "is_discrete", "obs_shape", "num_objectives", "action_spec",
           "target_updater", "actor_critic_optimizers", "orthogonal_critic_copies_", "eval_exploration", "epsilon",
           "epsilon_greedy"]


def captures(cfg) -> bool:
    """Whether ``cfg`` asks for a captured update (``compile`` / ``cudagraphs``)."""
    return bool(getattr(cfg, "compile", False) or getattr(cfg, "cudagraphs", False))


class Agent:
    """Holds the modules of one algorithm: what its recipe's ``update`` and loop act on, what a
    checkpoint saves and what the evaluator runs. The learning itself is in the algorithm's recipe
    module (its ``update`` and ``on_batch``), written once.

    Attributes:
        explore_policy: acts during collection (epsilon-greedy / stochastic).
        eval_policy: acts during evaluation, under ``eval_exploration`` (``cfg.eval_exploration``:
            greedy / mean action, or sampled actions).
        loss: the :class:`~torchrl.objectives.LossModule`.
        optimizers: name -> optimizer.
        target_updater: a ``SoftUpdate`` / :class:`~morl_trl.objectives.updaters.PeriodicHardUpdate`.
        critic_steps: the updates done (the delayed actor's clock; kept by the checkpoint).
        captured: the :class:`~morl_trl.training.capture.CapturedUpdate` of a recipe whose update runs
            captured (``compile`` / ``cudagraphs``, or fused optimizers on an accelerator), decided by
            :func:`captured_update` on the first update (``False``: eager;
            ``None``: not decided yet).
        last_actor_losses: the actor-critics' losses of the last actor turn, reported by the critic-only
            updates of the delayed actor (``None`` before the first).

    Args:
        capturable: whether the recipe's update can run captured; ``compile`` / ``cudagraphs`` are
            refused for an algorithm whose update cannot.
    """

    def __init__(self, cfg, loss, explore_policy, eval_policy, optimizers, target_updater,
                 *, device, exploration_module=None, eval_exploration=ExplorationType.DETERMINISTIC,
                 capturable: bool = False) -> None:
        self.cfg = cfg
        self.loss = loss
        self.explore_policy = explore_policy
        self.eval_policy = eval_policy
        self.optimizers = optimizers
        self.target_updater = target_updater
        self.device = device
        self.exploration_module = exploration_module
        self.eval_exploration = eval_exploration
        self.capturable = capturable
        self.captured = None
        self.last_actor_losses = None
        self.critic_steps = 0
        policy_freq = int(getattr(cfg, "policy_freq", 1))
        if policy_freq > 1 and not {"qvalue", "actor"} <= set(optimizers):
            raise ValueError(f"policy_freq={policy_freq} delays the actor of an actor-critic loss; "
                             f"{cfg.algo}'s optimizers are {sorted(optimizers)}: set policy_freq=1")
        if policy_freq > 1 and getattr(cfg, "joint_update", False):
            raise ValueError(f"joint_update=true steps every loss together at each update; policy_freq="
                             f"{policy_freq} delays the actor: set policy_freq=1 or joint_update=false")
        if captures(cfg) and not capturable:
            raise ValueError(f"compile / cudagraphs capture an update written for it (envelope, capql, mosac, "
                             f"mosac_discrete, sac); {cfg.algo}'s is not: set compile=false and cudagraphs=false")

    @property
    def replay_keys(self) -> list:
        """The entries of a transition the replay buffer keeps: those the loss reads (``loss.in_keys``; the
        collector's batch has more, which only the run's logs read)."""
        return list(self.loss.in_keys)

    def store(self, buffer, batch: TensorDictBase) -> None:
        """Write ``batch``'s transitions into ``buffer``, :attr:`replay_keys` only (an entry that a
        transition lacks, e.g. ``"preference"`` of an env without one, is left out)."""
        extend_selected(buffer, batch, self.replay_keys)

    @property
    def epsilon(self) -> float | None:
        """The current ε of the ε-greedy exploration (``None`` without one)."""
        return None if self.exploration_module is None else float(self.exploration_module.eps)

    # ------------------------------------------------------------------ state
    def state_dict(self) -> dict:
        return {
            "loss": self.loss.state_dict(),
            "optimizers": {k: o.state_dict() for k, o in self.optimizers.items()},
            "target_updater_counter": getattr(self.target_updater, "counter", None),  # HardUpdate's period
            "critic_steps": self.critic_steps,
        }

    def load_state_dict(self, state: dict) -> None:
        upgrade_agent_state(self, state)  # (in place: the subclasses read the converted entries too)
        self.loss.load_state_dict(state["loss"])
        for k, o in self.optimizers.items():
            o.load_state_dict(state["optimizers"][k])
            keep_implementation(o)
        self.critic_steps = int(state.get("critic_steps", 0))
        if state.get("target_updater_counter") is not None and hasattr(self.target_updater, "counter"):
            self.target_updater.counter = state["target_updater_counter"]


# ---------------------------------------------------------------------- shared by the builders
def updates_due(cfg, frames: int, batch_frames: int) -> int:
    """The updates an off-policy batch of ``batch_frames`` frames ending at ``frames`` earns:
    ``cfg.updates_per_batch``, or (0) one per ``cfg.update_frequency`` frames crossed (the authors'
    discrete SAC: every 4th).

    Example:
        >>> from types import SimpleNamespace
        >>> updates_due(SimpleNamespace(updates_per_batch=0, update_frequency=4), 70, 32)
        8
    """
    every = getattr(cfg, "update_frequency", 1)  # (Envelope, CAPQL, MOSAC, GPI have no such key: every frame)
    return cfg.updates_per_batch or frames // every - (frames - batch_frames) // every


@contextlib.contextmanager
def counted_update(done: int):
    """Around one of a batch's updates: a :class:`NonFiniteLossError` raised inside carries
    ``updates_done = done``, the updates of the batch applied before it (the run counts them)."""
    try:
        yield
    except NonFiniteLossError as err:
        err.updates_done = done
        raise


def runs_captured(agent) -> bool:
    """Whether ``agent``'s update runs captured: ``cfg.compile`` / ``cfg.cudagraphs``, or fused optimizers
    on an accelerator (the on-device guard); on the CPU otherwise the eager update checks on the host."""
    if not agent.capturable:
        return False
    fused = all(group.get("fused") for opt in agent.optimizers.values() for group in opt.param_groups)
    return captures(agent.cfg) or (torch.device(agent.device).type != "cpu" and fused)


def captured_update(agent, gradient_step):
    """The :class:`~morl_trl.training.capture.CapturedUpdate` of ``agent``'s ``gradient_step`` if its update
    runs captured (:func:`runs_captured`), else ``False`` (eager); the recipe keeps it as ``agent.captured``."""
    if not runs_captured(agent):
        return False
    from morl_trl.training.capture import CapturedUpdate  # (capture.py builds on this module)

    return CapturedUpdate(agent, gradient_step)


def epsilon(cfg, frames: int) -> float:
    """The ε of ε-greedy exploration after ``frames`` frames: ``cfg.eps_start`` until the learning starts
    (``cfg.init_random_frames``), then linear to ``cfg.eps_end`` over ``cfg.eps_frames`` frames, then constant (the
    one ε schedule). The decay starts at learning_starts as the authors' and MB's ``linearly_decaying_value(...,
    global_step, learning_starts, ...)`` (envelope.py, gpi_pd.py; SPEC §6 Envelope: "after that ε decays linearly.
    On LavaGrid the decay spans 5M steps, so ε ends at 0.050019", i.e. 100 frames of warm-up late).

    Example:
        >>> from types import SimpleNamespace
        >>> cfg = SimpleNamespace(eps_start=1.0, eps_end=0.5, eps_frames=100, init_random_frames=0)
        >>> epsilon(cfg, 0), epsilon(cfg, 50), epsilon(cfg, 1_000)
        (1.0, 0.75, 0.5)
        >>> lava = SimpleNamespace(eps_start=1.0, eps_end=0.05, eps_frames=5_000_000, init_random_frames=100)
        >>> round(epsilon(lava, 5_000_000), 6)
        0.050019
    """
    warm = int(getattr(cfg, "init_random_frames", 0) or 0)
    frac = min(1.0, max(0, frames - warm) / max(1, cfg.eps_frames))
    return cfg.eps_start + frac * (cfg.eps_end - cfg.eps_start)


def epsilon_greedy(cfg, env) -> EGreedyModule:
    """TorchRL's ``EGreedyModule`` for ``env``'s actions at ``epsilon(cfg, 0)``; the recipe sets its ε from
    :func:`epsilon` after every batch (TorchRL's own annealing, ``step()``, is not used)."""
    return EGreedyModule(env.full_action_spec, eps_init=cfg.eps_start, eps_end=cfg.eps_end,
                         annealing_num_steps=max(1, cfg.eps_frames))


def obs_shape(env) -> tuple[int, ...]:
    """The unbatched shape of the env's ``"observation"``."""
    return tuple(env.observation_spec["observation"].shape[len(env.batch_size):])


def num_objectives(env) -> int:
    """The width ``k`` of the env's vector reward."""
    return int(env.full_reward_spec[env.reward_key].shape[-1])


def action_spec(env):
    """The unbatched action spec."""
    spec = env.full_action_spec[env.action_key]
    return spec[(0,) * len(env.batch_size)] if len(env.batch_size) else spec


def is_discrete(spec) -> bool:
    return isinstance(spec, (Categorical, OneHot))


def eval_exploration(cfg) -> ExplorationType:
    """``cfg.eval_exploration`` as TorchRL's ``ExplorationType`` (``RANDOM`` samples the actor's actions)."""
    return ExplorationType.RANDOM if cfg.eval_exploration == "random" else ExplorationType.DETERMINISTIC


def target_updater(cfg, loss):
    """Polyak averaging with ``cfg.tau`` (:class:`~morl_trl.objectives.PolyakUpdate`), else a hard copy every
    ``cfg.target_update_period`` updates (:class:`~morl_trl.objectives.updaters.PeriodicHardUpdate`: exactly that
    period; TorchRL's ``HardUpdate`` copies every ``period + 1``)."""
    if cfg.tau is not None:
        return PolyakUpdate(loss, tau=cfg.tau)
    return PeriodicHardUpdate(loss, value_network_update_interval=cfg.target_update_period)


def actor_critic_optimizers(cfg, loss) -> dict:
    """Adam (:func:`adam`) for the actor (``lr``), the critics (``q_lr``) and, when learned, the
    temperature (``alpha_lr``), with ``adam_eps`` (an algorithm without one of these keys, e.g. CAPQL:
    ``lr`` and Adam's own eps)."""
    adam_eps, q_lr = getattr(cfg, "adam_eps", None), getattr(cfg, "q_lr", None)
    eps = {} if adam_eps is None else {"eps": adam_eps}
    q_lr = cfg.lr if q_lr is None else q_lr
    opts = {
        "actor": adam(loss.actor_network_params.values(True, True), cfg.lr, fused=fused_choice(cfg), **eps),
        "qvalue": adam(loss.qvalue_network_params.values(True, True), q_lr, fused=fused_choice(cfg), **eps),
    }
    if isinstance(getattr(loss, "log_alpha", None), nn.Parameter):
        alpha_lr = getattr(cfg, "alpha_lr", None)
        alpha_lr = cfg.lr if alpha_lr is None else alpha_lr
        opts["alpha"] = adam([loss.log_alpha], alpha_lr, fused=fused_choice(cfg), **eps)
    return opts


@torch.no_grad()
def orthogonal_critic_copies_(loss, critic, init_=None) -> None:
    """Give each of the loss's ``num_qvalue_nets`` critic copies (TorchRL re-draws the copies with
    PyTorch's init) its own orthogonal init (``init_``, default :func:`orthogonal_init_`: gain 1,
    zero biases; the authors' ``layer_init``), and its target the same values."""
    init_ = orthogonal_init_ if init_ is None else init_
    params = loss.qvalue_network_params.data
    for i in range(params.batch_size[0]):
        params[i].update_(TensorDict.from_module(init_(copy.deepcopy(critic))).data)
    target = getattr(loss, "target_qvalue_network_params", None)
    if target is not None:
        target.data.update_(params)
