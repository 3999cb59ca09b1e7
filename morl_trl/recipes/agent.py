"""What the off-policy recipe drives: an :class:`Agent` (loss, policies, optimizers, target
updates, schedules) and the pieces every agent builder shares.

The builders live with their algorithm (:mod:`morl_trl.recipes.envelope`,
:mod:`morl_trl.recipes.actor_critic`); :func:`morl_trl.recipes.build_agent` picks one by name.
"""

from __future__ import annotations

import copy

import torch
from tensordict import TensorDict, TensorDictBase
from torch import nn
from torchrl.data import Categorical, OneHot
from torchrl.envs.utils import ExplorationType
from torchrl.modules import EGreedyModule

from morl_trl.objectives import PolyakUpdate
from morl_trl.objectives.networks import orthogonal_init_
from morl_trl.objectives.updaters import PeriodicHardUpdate
from morl_trl.recipes.optim import NonFiniteLossError, adam, fused_choice, keep_implementation, optimizer_step
from morl_trl.recipes.state_upgrade import upgrade_agent_state

__all__ = ["Agent", "NonFiniteLossError", "apply_updates", "updates_due",
           "adam", "fused_choice", "is_discrete", "obs_shape", "num_objectives", "action_spec",
           "target_updater", "actor_critic_optimizers", "orthogonal_critic_copies_", "eval_exploration", "epsilon",
           "epsilon_greedy"]


def _captures(cfg) -> bool:
    return bool(getattr(cfg, "compile", False) or getattr(cfg, "cudagraphs", False))


class Agent:
    """Holds the modules of one algorithm and performs its updates.

    Attributes:
        explore_policy: acts during collection (epsilon-greedy / stochastic).
        eval_policy: acts during evaluation, under ``eval_exploration`` (``cfg.eval_exploration``:
            greedy / mean action, or sampled actions).
        loss: the :class:`~torchrl.objectives.LossModule`.
        optimizers: name -> optimizer; stepped together after one backward of the summed losses.
        target_updater: a ``SoftUpdate`` / :class:`~morl_trl.objectives.updaters.PeriodicHardUpdate` (stepped after every update).
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
        self._captured = None  # the compiled / CUDA-graphed / device-guarded update, built on first use
        self._guard = None
        self.critic_steps = 0  # updates done (the delayed actor's clock, policy_freq)
        self._actor_out = None  # the last actor turn's losses (delayed_actor_step)
        if self.policy_freq > 1 and not {"qvalue", "actor"} <= set(optimizers):
            raise ValueError(f"policy_freq={self.policy_freq} delays the actor of an actor-critic loss; "
                             f"{cfg.algo}'s optimizers are {sorted(optimizers)}: set policy_freq=1")
        if self.policy_freq > 1 and getattr(cfg, "joint_update", False):
            raise ValueError(f"joint_update=true steps every loss together at each update; policy_freq="
                             f"{self.policy_freq} delays the actor: set policy_freq=1 or joint_update=false")
        #: the update steps critics, actor(s), temperature one after the other, each loss computed alone
        #: (delayed_actor_step: the authors' actor-critic order), rather than one joint step of the summed losses
        self.steps_each_loss = (not getattr(cfg, "joint_update", False) and {"qvalue", "actor"} <= set(optimizers)
                                and all(hasattr(loss, m) for m in ("qvalue_loss", "actor_loss", "temperature_loss")))
        if _captures(cfg) and type(self).update is not Agent.update:
            raise ValueError(f"compile / cudagraphs capture Agent.update; {cfg.algo}'s agent "
                             f"({type(self).__name__}) writes its own update: set compile=false and cudagraphs=false")

    # ------------------------------------------------------------------ learning
    def learn(self, batch: TensorDictBase, buffer, frames: int) -> tuple[TensorDictBase | None, int]:
        """What the loop does with one collected batch: returns ``(last losses or None, updates done)``.

        Off-policy default: store the batch's transitions in ``buffer``, then, once ``frames``
        reaches ``cfg.init_random_frames``, ``cfg.updates_per_batch`` :meth:`update` calls (0: one
        per ``cfg.update_frequency`` collected frames). An algorithm whose learning differs (on-policy, episodic, a
        weight-support loop) overrides this and keeps the rest of the run (collection,
        evaluation, checkpoints, logs) as it is. Raises :class:`NonFiniteLossError` as
        :meth:`update` does, with ``updates_done``: the updates applied before it.
        """
        self.store(buffer, batch)
        if frames < self.cfg.init_random_frames:
            return None, 0
        n = updates_due(self.cfg, frames, batch.numel())
        return self.run_updates(buffer, n), n

    @property
    def replay_keys(self) -> list:
        """The entries of a transition that the replay buffer keeps: those the loss reads
        (``loss.in_keys``). The collector's batch has many more (episode returns, the
        ``"next"`` preference, the policy's action values, ...), which only the run's logs read."""
        return list(self.loss.in_keys)

    def store(self, buffer, batch: TensorDictBase) -> None:
        """Write ``batch``'s transitions into ``buffer``, :attr:`replay_keys` only (an entry that a
        transition lacks, e.g. ``"preference"`` of an env without one, is left out)."""
        buffer.extend(batch.reshape(-1).select(*self.replay_keys, strict=False))

    def frames_of(self, batch: TensorDictBase) -> int:
        """How many frames ``batch`` counts against the run's budget ``cfg.frames``: all of them
        (PGMORL counts one member's, as the authors)."""
        return batch.numel()

    def before_batch(self) -> bool:
        """Called by the training loop before a batch is collected (once the collector is built, then
        after every batch's :meth:`learn`); ``True``: restart every episode first (``collector.reset()``).
        Default: nothing to do (MORL/D's round robin resets at an exchange, PGMORL re-seeds its simulators)."""
        return False

    def after_step(self, buffer) -> None:
        """Called by the training loop after each batch's ``run.step`` (its evaluation and checkpoint when
        due), and once when a resumed run's session has restored its state and RNG. Default: nothing (GPI begins its next
        iteration here, so that an evaluation at an iteration's end acts with the support it trained on)."""

    def frames_to_collect(self, frames_done: int) -> int:
        """The frames the collector still has to collect when ``frames_done`` frames (as
        :meth:`frames_of` counts them) are done: ``cfg.frames - frames_done``."""
        return self.cfg.frames - frames_done

    def run_updates(self, buffer, n: int) -> TensorDictBase | None:
        """``n`` :meth:`update` calls (:func:`apply_updates`)."""
        return apply_updates(lambda: self.update(buffer), n)

    def update(self, buffer) -> TensorDictBase:
        """One gradient step on a sampled batch; a non-finite loss is never applied.

        With ``cfg.max_grad_norm`` the gradient norm of each optimizer's parameters is clipped to
        it (``torch.nn.utils.clip_grad_norm_``) before stepping, as MORL-Baselines clips each
        network's (Envelope: 1.0).

        On the CPU (eager) the loss is checked on the host before anything is stepped and
        :class:`NonFiniteLossError` is raised at once. With the update captured
        (``cfg.compile`` / ``cfg.cudagraphs``, see :mod:`morl_trl.recipes.capture`), and on
        accelerators whenever the optimizers are fused (no host synchronisation per update),
        the check stays on the device: a non-finite update is skipped there (the fused
        optimizers' ``found_inf``, a masked Polyak step, priorities written as 0) and the count
        of skipped updates is read every ``cfg.finite_check_interval`` updates, raising
        :class:`NonFiniteLossError` then.
        """
        if self._device_guard():
            return self._captured_update(None, buffer)  # samples itself (in the graph, where it can)
        batch = self.sample(buffer)
        actor_turn = self.next_is_actor_turn()
        if self.steps_each_loss:
            out, _ = self.delayed_actor_step(batch, actor_turn)
        else:
            out = self.loss(batch)
            optimizer_step(sum(out[k] for k in self.loss_keys), self.optimizers.values(),
                           max_grad_norm=self.max_grad_norm, losses={k: out[k] for k in self.loss_keys})
        self.target_updater.step()
        if self.cfg.prioritized:
            buffer.update_tensordict_priority(batch)
        return out.detach()

    @property
    def policy_freq(self) -> int:
        """``cfg.policy_freq``: 1 = an actor step at every update; ``n > 1`` = the delayed actor
        (:meth:`delayed_actor_step`), as the authors' continuous SAC and MOSAC (``n = 2``)."""
        return int(getattr(self.cfg, "policy_freq", 1))

    def next_is_actor_turn(self) -> bool:
        """Counts one more update; whether it is an actor turn (every ``policy_freq``-th: the 2nd, 4th, ...
        for 2, as the authors' ``global_step % policy_freq == 0`` with an even ``learning_starts``; every
        update for 1)."""
        self.critic_steps += 1
        return self.critic_steps % self.policy_freq == 0

    def delayed_actor_step(self, batch: TensorDictBase, actor_turn: bool, *, on_device: bool = False):
        """The authors' actor-critic step (CleanRL's SAC; their ``sac_continuous.py:435-456``,
        ``mosac_continuous_action.py:460-482``), each loss computed alone (the loss's
        ``qvalue_loss`` / ``actor_loss`` / ``temperature_loss``, TorchRL's SACLoss parts):

        1. the critic step: ``qvalue_loss`` (targets, critics) and the ``qvalue`` optimizer;
        2. on an actor turn, ``policy_freq`` times: ``actor_loss`` (fresh actions, the updated
           critics; no target computation) and the ``actor`` optimizer, then, when the
           temperature is learned, ``temperature_loss`` and the ``alpha`` optimizer, on a fresh
           sample of the just-updated actor where the loss says so (``fresh_temperature_sample``:
           continuous, the authors' ``with no_grad: _, log_pi, _ = actor.get_action(obs)`` after the
           actor step) or on the actor step's log-probabilities (discrete, ``mosac_discrete_action.py:490-492``).

        A non-finite loss is never applied: eager, :class:`NonFiniteLossError` is raised before its
        step (the steps of this update before it stay applied, as in the authors' order they must come
        first); on the device its step and every later one of the update are skipped.

        Returns ``(losses, found_inf)`` (``found_inf``: ``None`` unless ``on_device``). ``losses``
        has the keys of the loss's ``forward``; on a critic-only update the actor's and the
        temperature's are those of the last actor turn (NaN before the first).
        """
        loss = self.loss
        kw = dict(max_grad_norm=self.max_grad_norm, on_device=on_device)
        loss_qvalue, _ = loss.qvalue_loss(batch)
        found = optimizer_step(loss_qvalue, [self.optimizers["qvalue"]], losses={"loss_qvalue": loss_qvalue}, **kw)
        if actor_turn:
            alpha_opt = self.optimizers.get("alpha")
            dist = None
            for i in range(self.policy_freq):
                loss_actor, meta = loss.actor_loss(batch) if dist is None else loss.actor_loss(batch, dist)
                # on the device a skipped part skips the rest of the update (found_inf carried on)
                found = optimizer_step(loss_actor, [self.optimizers["actor"]], losses={"loss_actor": loss_actor},
                                       found_inf=found, **kw)
                actor_out = {"loss_actor": loss_actor.detach(), "entropy": -meta["log_prob"].mean(-1)}
                if alpha_opt is not None:
                    if loss.fresh_temperature_sample:
                        # one forward of the updated actor for the temperature's fresh sample and, drawn after
                        # it, the next actor step's sample (the actor does not change in between)
                        dist = loss.actor_dist(batch) if i + 1 < self.policy_freq else None
                        loss_alpha = loss.temperature_loss(batch, dist=dist)
                    else:
                        loss_alpha = loss.temperature_loss(batch, meta["log_prob"])
                    found = optimizer_step(loss_alpha, [alpha_opt], losses={"loss_alpha": loss_alpha},
                                           found_inf=found, **kw)
                    actor_out["loss_alpha"] = loss_alpha.detach()
            self._actor_out = actor_out
        elif self._actor_out is None:  # no actor turn yet
            nan = torch.full_like(loss_qvalue.detach(), float("nan"))
            self._actor_out = {"loss_actor": nan, "entropy": torch.full_like(loss.log_alpha.detach(), float("nan"))}
            if "alpha" in self.optimizers:
                self._actor_out["loss_alpha"] = nan
        with torch.no_grad():
            alpha = loss.log_alpha.exp()
        out = TensorDict({"loss_qvalue": loss_qvalue.detach(), **self._actor_out, "alpha": alpha}, batch_size=[])
        return out, found

    @property
    def max_grad_norm(self) -> float | None:
        """Each optimizer's parameters' gradient norm is clipped to this (``cfg.max_grad_norm``; ``None``: no clipping)."""
        return getattr(self.cfg, "max_grad_norm", None)

    def sample(self, buffer) -> TensorDictBase:
        """The batch of one update, on the agent's device (MORL/D: one per population member)."""
        return buffer.sample().to(self.device)

    @property
    def samples_one_batch(self) -> bool:
        """Whether :meth:`sample` is this class's (one ``buffer.sample()``), which a captured update may replace."""
        return type(self).sample is Agent.sample

    @property
    def captured_update(self) -> bool:
        """Whether :meth:`update` runs captured (:class:`~morl_trl.recipes.capture.CapturedUpdate`:
        ``cfg.compile`` / ``cfg.cudagraphs``, or fused optimizers on an accelerator)."""
        return self._device_guard()

    def _device_guard(self) -> bool:
        """Whether updates go through :class:`~morl_trl.recipes.capture.CapturedUpdate` (decided once)."""
        if self._captured is not None:
            return True
        if self._guard is None:
            fused = all(group.get("fused") for opt in self.optimizers.values() for group in opt.param_groups)
            self._guard = _captures(self.cfg) or (torch.device(self.device).type != "cpu" and fused)
        return self._guard

    def _captured_update(self, batch: TensorDictBase, buffer) -> TensorDictBase:
        from morl_trl.recipes.capture import CapturedUpdate

        if self._captured is None:
            self._captured = CapturedUpdate(self)
        return self._captured(batch, buffer)

    @property
    def epsilon(self) -> float | None:
        """The current ε of the ε-greedy exploration (``None`` without one)."""
        return None if self.exploration_module is None else float(self.exploration_module.eps)

    def on_frames(self, frames: int) -> None:
        """Advance the frame-based schedules (epsilon, homotopy)."""
        if self.exploration_module is not None:
            self.exploration_module.eps.fill_(epsilon(self.cfg, frames))
        if hasattr(self.loss, "update_homotopy"):
            self.loss.update_homotopy(frames)

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
    every = cfg.update_frequency
    return cfg.updates_per_batch or frames // every - (frames - batch_frames) // every


def apply_updates(update, n: int):
    """``n`` calls of ``update()``; returns the last one's losses (``None`` for ``n = 0``). A
    :class:`NonFiniteLossError` carries ``updates_done``: the updates applied before it (the run counts them).

    Example:
        >>> apply_updates(lambda: 1.0, 3), apply_updates(lambda: 1.0, 0)
        (1.0, None)
    """
    losses = None
    for i in range(n):
        try:
            losses = update()
        except NonFiniteLossError as err:
            err.updates_done = i
            raise
    return losses


def epsilon(cfg, frames: int) -> float:
    """The ε of ε-greedy exploration after ``frames`` frames: linear from ``cfg.eps_start`` to
    ``cfg.eps_end`` over ``cfg.eps_frames`` frames, then constant (the one ε schedule).

    Example:
        >>> from types import SimpleNamespace
        >>> cfg = SimpleNamespace(eps_start=1.0, eps_end=0.5, eps_frames=100)
        >>> epsilon(cfg, 0), epsilon(cfg, 50), epsilon(cfg, 1_000)
        (1.0, 0.75, 0.5)
    """
    frac = min(1.0, frames / max(1, cfg.eps_frames))
    return cfg.eps_start + frac * (cfg.eps_end - cfg.eps_start)


def epsilon_greedy(cfg, env) -> EGreedyModule:
    """TorchRL's ``EGreedyModule`` for ``env``'s actions at ``epsilon(cfg, 0)``; :meth:`Agent.on_frames`
    sets its ε from :func:`epsilon` after every batch (TorchRL's own annealing, ``step()``, is not used)."""
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
    temperature (``alpha_lr``), with ``adam_eps``."""
    eps = {} if cfg.adam_eps is None else {"eps": cfg.adam_eps}
    q_lr = cfg.lr if cfg.q_lr is None else cfg.q_lr
    opts = {
        "actor": adam(loss.actor_network_params.values(True, True), cfg.lr, fused=fused_choice(cfg), **eps),
        "qvalue": adam(loss.qvalue_network_params.values(True, True), q_lr, fused=fused_choice(cfg), **eps),
    }
    if isinstance(getattr(loss, "log_alpha", None), nn.Parameter):
        alpha_lr = cfg.lr if cfg.alpha_lr is None else cfg.alpha_lr
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
