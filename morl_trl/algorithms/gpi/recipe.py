"""GPI-LS and GPI-PD (Alegre et al., AAMAS 2023): ``morl-trl train gpi_ls|gpi_pd``, read top to bottom.

:func:`train_gpi` is the recipe (env -> modules and loss -> buffer and collector -> the loop), for
discrete and continuous actions; with its losses (:class:`~morl_trl.objectives.GPILoss`,
:class:`~morl_trl.objectives.gpi.GPIContinuousLoss`) it is everything GPI does per frame. Its loop is
the authors' weight-support loop (MORL-Baselines' ``GPIPD.train`` / ``train_iteration``): per collected
batch :func:`on_batch` (with :func:`update`, the one gradient update), then the run's step (evaluation,
checkpoint), then :meth:`GPIAgent.begin_pending_iteration`. What it keeps between batches and checkpoints
is a :class:`GPIAgent` (the modules, the linear support, ``w`` and ``M``, GPI-PD's model buffer), whose
named steps these call: :meth:`GPIAgent.sample_batch`, :meth:`GPIAgent.fit_model`,
:meth:`GPIAgent.rollout_model`, :meth:`GPIAgent.end_iteration`, :meth:`GPIAgent.begin_iteration`. Per batch:

1. Every ``gpi_iteration_frames`` frames an iteration ends: the GPI policy over the support
   ``M`` is evaluated (``gpi_front_episodes`` episodes per weight, in the training domain,
   discounted vector returns) at every weight of ``M`` and each value is added to the linear
   support (:class:`~morl_trl.preferences.linear_support.LinearSupport`).
2. The next iteration's weight ``w``: the corner weights of the CCS, each prioritised by
   how much the GPI policy over the CCS's weight support improves on the CCS there (the
   first ``k`` iterations take the extrema). ``M`` = the CCS's weights + the 4 best corners + ``w``.
3. Collection: when an iteration begins every sub-env is reset and its first episode acts with
   ``w``; each later episode draws its preference from ``M`` (the authors'
   ``change_w_every_episode``, SPEC §6; ``gpi_first_episode="support"``: no reset, every new
   episode from ``M``); actions are epsilon-greedy around GPI over ``M`` and the sub-env's
   preference. PER priorities are recomputed for the whole buffer under ``w``.
4. Updates (:class:`~morl_trl.objectives.GPILoss`; the first half of each doubled batch under
   ``w``, or with ``gpi_update_weight="episode"`` MORL-Baselines' reading, the weight of sub-env
   0's episode at the batch's last step): 1 per frame, ``gpi_gradient_updates``
   per frame once ``frames >= gpi_dynamics_rollout_starts`` (the authors' gating, for GPI-LS
   too; every script of theirs passes ``gradient_updates 1``, so 1 per frame throughout);
   a hard target copy every ``target_update_period`` frames.
5. GPI-PD only: every ``gpi_dynamics_train_freq`` frames the dynamics ensemble is refitted on
   the whole buffer (:func:`~morl_trl.objectives.fit_dynamics`); every
   ``gpi_dynamics_rollout_freq`` frames from ``gpi_dynamics_rollout_starts``,
   ``gpi_dynamics_rollout_batch`` stored observations are stepped once through the model with
   the GPI action for ``w``, and the transitions with uncertainty below
   ``gpi_uncertainty_threshold`` go to a model buffer; updates then draw ``gpi_real_ratio``
   of each batch from the real buffer and the rest from the model buffer.

Evaluation goes through :class:`~morl_trl.evaluation.MultiContextEvaluator` only, as for every
method. The run's evaluator (:func:`~morl_trl.training.parts.make_evaluator`: the suite's contexts,
the run's weights and seed, the same result files) acts by GPI over ``M`` for each evaluation
weight, as the authors: discrete with dropout off, continuous over the candidate actions
``pi(s, w_j)`` with the critic's dropout on and, by default, the critic conditioned as the
authors' vectorised evaluator did (``gpi_eval_conditioning``, see
:class:`~morl_trl.objectives.gpi.GPIContinuousPolicy`; its table of contexts is the evaluator's,
:func:`~morl_trl.evaluation.suite_contexts`). The CCS values are Monte-Carlo discounted returns of
the GPI policy (``gpi_front_episodes`` per weight) from a second evaluator on the same env with no
context given at reset: each episode's context is drawn by the training id's sampler, as the
authors evaluated on their DR training env (SPEC §6), never on the evaluation suite
(:attr:`GPIAgent.front_evaluator`).

Example:
    >>> from morl_trl.recipes import resolve_config
    >>> from morl_trl.recipes.off_policy import make_training_env
    >>> cfg = resolve_config("gpi_ls", "MOLavaGridDR-v0", quick=True, hidden=(16, 16), num_envs=2)
    >>> env = make_training_env(cfg, torch.device("cpu"))
    >>> agent = make_gpi_agent(cfg, env, gamma=0.995, device=torch.device("cpu"))
    >>> agent.weight, agent.support.shape
    (array([1., 0.]), (2, 2))
"""

from __future__ import annotations

import warnings

import numpy as np
import torch
from tensordict import TensorDict, TensorDictBase
from torchrl.data import LazyTensorStorage, TensorDictReplayBuffer

from morl_trl.envs import domain_of
from morl_trl.evaluation import MultiContextEvaluator, suite_contexts
from morl_trl.objectives import (DynamicsLoss, GPILoss, GPIPolicy, GPIQNetwork, LeanSequential, ProbabilisticEnsemble,
                                 fit_dynamics)
from morl_trl.objectives.dynamics import MODEL_TERMINATION, model_inputs, model_termination
from morl_trl.objectives.gpi import GPIActor, GPIContinuousLoss, GPIContinuousPolicy, GPIVectorCritic, gpi_action
from morl_trl.objectives.updaters import PeriodicHardUpdate, polyak_
from morl_trl.preferences.linear_support import LinearSupport, unique_weights
from morl_trl.training.agent import (Agent, action_spec, counted_update, epsilon, epsilon_greedy, is_discrete,
                                    num_objectives, obs_shape)
from morl_trl.training.allocator import tune_malloc
from morl_trl.training.optim import adam, check_finite, fused_choice, optimizer_step
from morl_trl.training.parts import (
    load_agent_state,
    checkpoint_snapshot,
    check_buffer_memory,
    evaluation_contexts,
    load_reference,
    make_collector,
    make_evaluator,
    make_replay_buffer,
    make_training_env,
    policy_env_factory,
    run_discount,
    run_domain,
    start_notes,
)
from morl_trl.runs.env_state import transforms_of
from morl_trl.runs.run import Run
from morl_trl.transforms import PreferenceConditioning

__all__ = ["GPIAgent", "make_gpi_agent", "on_batch", "train_gpi", "update"]

_KEYS = ("observation", "action", ("next", "observation"), ("next", "reward"), ("next", "terminated"),
         ("next", "done"))


class GPIAgent(Agent):
    """GPI-LS / GPI-PD's state between batches and checkpoints, and the weight-support loop's named steps around
    :class:`~morl_trl.objectives.GPILoss` (see the module); the gradient update and the per-batch step are the
    module's :func:`update` and :func:`on_batch`."""

    def __init__(self, cfg, loss: GPILoss, explore_policy, eval_policy: GPIPolicy, optimizers, *, device,
                 exploration_module, gamma: float, preference_transform: PreferenceConditioning | None,
                 num_actions: int | None, dynamics: DynamicsLoss | None = None, gpi_policy=None) -> None:
        # (a copy at every step() call: the loop calls it once per target_update_period frames)
        updater = PeriodicHardUpdate(loss, value_network_update_interval=1) if num_actions is not None else None
        super().__init__(cfg, loss, explore_policy, eval_policy, optimizers, updater,
                         device=device, exploration_module=exploration_module)
        self.gpi_policy = eval_policy if gpi_policy is None else gpi_policy
        self.continuous = num_actions is None
        self.continuous_updates = 0
        self.gamma = gamma
        self.k = loss.num_objectives
        self.num_actions = num_actions
        self.preference_transform = preference_transform
        self.dynamics = dynamics
        self.model_buffer = None
        if dynamics is not None:
            self.model_buffer = TensorDictReplayBuffer(storage=LazyTensorStorage(cfg.gpi_dynamics_buffer, device=device),
                                                       batch_size=cfg.batch_size)
        self.linear_support = LinearSupport(self.k, seed=cfg.seed)
        self.weight: np.ndarray | None = None
        self.support: np.ndarray | None = None
        self.iteration = 0
        self.iteration_end = cfg.gpi_iteration_frames
        #: an iteration ended and the next begins at :meth:`begin_pending_iteration` (after the run's evaluation)
        self.begin_pending = False
        self.evaluations = 0
        self._front_evaluator = None
        self.frames = 0
        self.begin_iteration(None)

    # ------------------------------------------------------------------ weights
    def _apply_weights(self) -> None:
        support = torch.as_tensor(self.support, dtype=torch.float32)
        self.loss.set_weights(torch.as_tensor(self.weight, dtype=torch.float32), support)
        for policy in {id(p): p for p in self._gpi_policies()}.values():
            policy.set_support(support)
        if self.preference_transform is not None:  # each sub-env's episode weight: a random row of M
            self.preference_transform.weights = support.clone()
            self.preference_transform.mode = "random"

    def _gpi_policies(self) -> list:
        kinds = (GPIPolicy, GPIContinuousPolicy)
        return [m for m in self.explore_policy.modules() if isinstance(m, kinds)] + [self.eval_policy, self.gpi_policy]

    @property
    def front_evaluator(self) -> MultiContextEvaluator:
        """The evaluator of the CCS values: the run's evaluation env (:func:`~morl_trl.training.parts.policy_env_factory`)
        with no context given at reset, so that each episode runs on a context the training id's sampler
        draws (the authors' ``policy_evaluation_mo`` on their DR training env, SPEC §6), ``gpi_front_episodes``
        episodes per weight, the run's discount; the weights and seed are those of each call."""
        if self._front_evaluator is None:
            self._front_evaluator = MultiContextEvaluator(
                self.gpi_policy, None, weights=np.eye(self.k), episodes=self.cfg.gpi_front_episodes, gamma=self.gamma,
                env_factory=policy_env_factory(self.cfg, self.device), device=self.device, seed=self.cfg.seed,
                sorl_key=None)
        return self._front_evaluator

    def _evaluate(self, weights: np.ndarray, support: np.ndarray, policy=None) -> np.ndarray:
        """``[m, k]``: the mean discounted vector return of ``policy`` (GPI over ``support``) at each of
        ``weights`` ``[m, k]``, from :attr:`front_evaluator` (a new seed, so new contexts, every call)."""
        policy = self.eval_policy if policy is None else policy
        policy.set_support(torch.as_tensor(support, dtype=torch.float32))
        self.evaluations += 1
        result = self.front_evaluator.evaluate(policy, weights=weights, seed=self.cfg.seed + 10_000 * self.evaluations)
        return result.returns.mean(dim=(0, 2)).numpy()  # [contexts=1, m, episodes, k] -> [m, k]

    def end_iteration(self) -> None:
        """The end of an iteration: the GPI policy over ``M`` evaluated at every weight of ``M``
        (:attr:`front_evaluator`), each value added to the linear support."""
        # the CCS values: Monte-Carlo discounted returns of the GPI policy over M (the authors', both action types)
        values = self._evaluate(self.support, self.support, self.gpi_policy)
        for v, w in zip(values, self.support):
            self.linear_support.add_solution(v, w)

    def begin_iteration(self, buffer, collector=None) -> None:
        """The next iteration: its weight ``w`` (the extrema first, then the corner weight of the CCS with the
        highest GPI priority), the support ``M`` (the CCS's weights + the 4 best corners + ``w``) set on the loss,
        the policies and the sub-envs' preferences; the discrete PER priorities of ``buffer`` recomputed under ``w``.
        With ``gpi_first_episode="w"`` (the authors') every sub-env's next episode acts with ``w``, and
        ``collector`` (when given) is reset so that this episode starts now, as the authors' ``train_iteration``
        resets its env (SPEC §6); without a collector (the first iteration, before the collector's own first
        reset) each sub-env's next reset gives it ``w``."""
        ls = self.linear_support
        if ls.ccs:
            ccs_support = np.stack(ls.get_weight_support())
            corners = ls.corner_weights()
            w = ls.next_weight(gpi_values=self._evaluate(corners, ccs_support, self.gpi_policy))
        else:
            w = ls.next_weight()
        if w is None:  # no corner left (only with an epsilon): keep training on the last weight
            w = self.weight
        self.weight = np.asarray(w, np.float64)
        self.support = unique_weights(ls.get_weight_support() + ls.get_corner_weights(top_k=4) + [self.weight])
        self.iteration += 1
        self.begin_pending = False
        self._apply_weights()
        if buffer is not None and self.cfg.prioritized and len(buffer) and not self.continuous:  # (discrete only)
            self._reset_priorities(buffer)
        if self.cfg.gpi_first_episode == "w" and self.preference_transform is not None:
            self.preference_transform.set_next_preference(torch.as_tensor(self.weight, dtype=torch.float32))
            if collector is not None:
                collector.reset()  # (the episode in progress ends here, as the authors' env.reset() at train_iteration)

    @torch.no_grad()
    def _reset_priorities(self, buffer, chunk: int = 1000) -> None:
        """The authors' ``_reset_priorities``: every stored transition's priority under the new ``w``."""
        n = len(buffer)
        for start in range(0, n, chunk):
            index = torch.arange(start, min(start + chunk, n))
            td = buffer.storage[index].to(self.device)
            buffer.update_priority(index, self.loss.priorities(td))

    def begin_pending_iteration(self, buffer, collector=None) -> None:
        """The next iteration (:meth:`begin_iteration`) once the one that ended (``begin_pending``) has been
        evaluated: :func:`train_gpi` calls this after ``run.step``, so an evaluation due at an iteration's end
        acts by GPI over the support ``M`` that iteration trained on, as MORL-Baselines' ``GPIPD.train`` (its
        evaluation after ``add_solution``, before the next ``next_weight``) and the parity harness's MB side
        (evaluated inside the env step). Evaluated over the next ``M`` instead (new corner weights not yet
        trained on), deep-sea-treasure seed 11 read 0.663 at 20k frames where the trained ``M`` gave 0.844.
        Not after the run's last frame (MB begins no iteration after its last)."""
        if self.begin_pending and self.frames < self.cfg.frames:
            self.begin_iteration(buffer, collector)

    # ------------------------------------------------------------------ learning
    def use_episode_weight(self, batch: TensorDictBase) -> None:
        """``gpi_update_weight="episode"`` (MORL-Baselines 1.3.0's reading: its ``update(tensor_w)`` with the
        weight of the episode in progress, gpi_pd.py:763,785-786): the loss's ``w`` for the coming updates is the
        preference sub-env 0 acted with at ``batch``'s last step; :meth:`begin_iteration` sets it back to the
        iteration's ``w`` (the PER priorities it recomputes are under that ``w``, as in MB)."""
        key = "preference" if self.preference_transform is None else self.preference_transform.preference_key
        pref = batch.get(key, None)
        if pref is None:
            raise ValueError("gpi_update_weight='episode' needs the collected preference (a PreferenceConditioning "
                             "transform on the training env)")
        w = pref.reshape(-1, batch.shape[-1], self.k)[0, -1]
        self.loss.current_weight.copy_(w.to(self.loss.current_weight.device, torch.float32))

    def sample_batch(self, buffer):
        """``(batch, real part)``: ``gpi_real_ratio`` real transitions and model ones once the model buffer has some."""
        cfg = self.cfg
        if self.model_buffer is None or not len(self.model_buffer) or self.frames < cfg.gpi_dynamics_rollout_starts:
            real = buffer.sample().to(self.device)
            return real, real
        n_real = int(cfg.batch_size * cfg.gpi_real_ratio)
        real = buffer.sample(n_real).to(self.device)
        model = self.model_buffer.sample(cfg.batch_size - n_real)
        batch = torch.cat([real.select(*_KEYS), model.select(*_KEYS)])
        return batch, real

    # ------------------------------------------------------------------ Dyna
    def _dyna(self, buffer, prev: int, frames: int) -> None:
        """GPI-PD's Dyna for a batch that took the frames from ``prev`` to ``frames``: :meth:`fit_model` when it
        crossed a multiple of ``gpi_dynamics_train_freq``, :meth:`rollout_model` when it crossed one of
        ``gpi_dynamics_rollout_freq`` from ``gpi_dynamics_rollout_starts`` on."""
        cfg = self.cfg
        if frames // cfg.gpi_dynamics_train_freq > prev // cfg.gpi_dynamics_train_freq:
            self.fit_model(buffer)
        if frames >= cfg.gpi_dynamics_rollout_starts and \
                frames // cfg.gpi_dynamics_rollout_freq > prev // cfg.gpi_dynamics_rollout_freq:
            self.rollout_model(buffer)

    def fit_model(self, buffer) -> None:
        """Refit the dynamics ensemble on every transition of the real ``buffer``
        (:func:`~morl_trl.objectives.fit_dynamics`: the authors' bootstrap, mini-batches, early stopping)."""
        data = buffer.storage[torch.arange(len(buffer))].to(self.device)
        x, y = self.dynamics.inputs_targets(data)
        fit_dynamics(self.dynamics, x.float(), y.float(), lr=self.cfg.gpi_dynamics_lr,
                     max_grad_norm=self.cfg.gpi_dynamics_max_grad_norm)

    @torch.no_grad()
    def rollout_model(self, buffer) -> int:
        """``gpi_dynamics_rollout_len`` model steps from ``ceil(gpi_dynamics_rollout_batch / 10k)`` chunks of
        (at most) 10k start states sampled from the real buffer (by priority with PER), as the authors: GPI
        actions for ``w`` (discrete) or the noisy actor (continuous); the confident transitions go to the
        model buffer, terminated by the authors' termination function of the domain
        (:func:`~morl_trl.objectives.dynamics.model_termination`), and the rollout continues from the
        non-terminal ones. Returns how many were stored."""
        cfg, k = self.cfg, self.k
        added = 0
        total = cfg.gpi_dynamics_rollout_batch
        chunks = -(-total // 10_000)  # the authors: ceil(batch / 10k) chunks of 10k start states (25k -> 30k)
        size = min(total, 10_000)
        support = torch.as_tensor(self.support, dtype=torch.float32, device=self.device)
        w = torch.as_tensor(self.weight, dtype=torch.float32, device=self.device)
        kind = MODEL_TERMINATION.get(domain_of(cfg.env_id).train_id)
        for _ in range(chunks):
            # start states drawn from the real buffer by priority (the authors' PER sample), uniformly without PER
            with warnings.catch_warnings():
                warnings.filterwarnings("ignore", message="Got conflicting batch_sizes")
                obs = buffer.sample(size)["observation"].to(self.device).float()
            for _ in range(cfg.gpi_dynamics_rollout_len):
                action = self._model_action(obs, w, support)
                y, unc = self.dynamics.model.step(model_inputs(obs, action, self.num_actions))
                next_obs = obs + y[:, k:]
                term = model_termination(kind, next_obs, y[:, :k], hopper_abs=cfg.gpi_model_termination == "corrected")
                keep = unc < cfg.gpi_uncertainty_threshold
                n = int(keep.sum())
                if n:
                    done = term[keep].unsqueeze(-1)
                    self.model_buffer.extend(TensorDict({
                        "observation": obs[keep], "action": action[keep],
                        ("next", "observation"): next_obs[keep], ("next", "reward"): y[keep, :k],
                        ("next", "terminated"): done, ("next", "done"): done.clone()}, batch_size=[n]))
                added += n
                obs = next_obs[~term]  # rollouts continue from the non-terminal predicted states
                if not obs.shape[0]:
                    break
        return added

    def _model_action(self, obs: torch.Tensor, w: torch.Tensor, support: torch.Tensor) -> torch.Tensor:
        """The action imagined rollouts take: GPI for ``w`` (discrete), the noisy actor (continuous), as the authors."""
        n, k = obs.shape[0], self.k
        if self.continuous:
            return self.loss.actor_network.module(obs, w.expand(n, k), self.cfg.gpi_policy_noise, self.cfg.gpi_noise_clip)
        m = support.shape[0]
        q = self.loss.value_network.module(obs.unsqueeze(1).expand(-1, m, -1), support.expand(n, m, k),
                                           members=slice(0, 1))[0]
        return gpi_action(q, w.expand(n, k))[0]

    # ------------------------------------------------------------------ state
    def state_dict(self) -> dict:
        state = super().state_dict()
        state.update(linear_support=self.linear_support.state_dict(), weight=self.weight, support=self.support,
                     iteration=self.iteration, iteration_end=self.iteration_end, evaluations=self.evaluations,
                     begin_pending=self.begin_pending,
                     frames=self.frames, updates=self.continuous_updates,
                     dynamics=None if self.dynamics is None else self.dynamics.model.state_dict())
        return state

    def load_state_dict(self, state: dict) -> None:
        super().load_state_dict(state)
        self.linear_support.load_state_dict(state["linear_support"])
        self.weight, self.support = np.asarray(state["weight"]), np.asarray(state["support"])
        self.iteration, self.iteration_end = state["iteration"], state["iteration_end"]
        self.begin_pending = bool(state.get("begin_pending", False))
        self.evaluations, self.frames, self.continuous_updates = state["evaluations"], state["frames"], state.get("updates", 0)
        if self.preference_transform is not None:  # (the env's state, restored with the run, says what is pending)
            self.preference_transform.set_next_preference(None)
        if self.dynamics is not None and state.get("dynamics") is not None:
            self.dynamics.model.load_state_dict(state["dynamics"])
        self._apply_weights()


def make_gpi_agent(cfg, env, *, gamma: float, device: torch.device) -> GPIAgent:
    """The GPI-LS (``cfg.algo == "gpi_ls"``) or GPI-PD (``"gpi_pd"``) agent for ``env``: discrete actions
    (:class:`~morl_trl.objectives.GPILoss`) or continuous ones (:class:`~morl_trl.objectives.gpi.GPIContinuousLoss`)."""
    spec = action_spec(env)
    if not is_discrete(spec):
        return _make_continuous_gpi_agent(cfg, env, spec, gamma=gamma, device=device)
    shape = obs_shape(env)
    pd = cfg.algo == "gpi_pd"
    if pd and len(shape) != 1:
        raise ValueError(f"gpi_pd needs flat observations (its dynamics model is an MLP); {cfg.env_id} has shape "
                         f"{shape}: use gpi_ls (the paper ran GPI-PD on LunarLander and Hopper only)")
    k, num_actions = num_objectives(env), spec.space.n
    qnet = GPIQNetwork(shape[0] if len(shape) == 1 else shape, num_actions, k, hidden=cfg.hidden, num_nets=cfg.gpi_num_nets,
                       dropout=cfg.gpi_dropout, layer_norm=cfg.gpi_layer_norm).to(device)
    loss = GPILoss(qnet, gpi_pd=pd, min_priority=cfg.gpi_min_priority)
    loss.make_value_estimator(gamma=gamma)
    greedy = GPIPolicy(qnet, include_preference=True)  # dropout on while acting, as the authors
    egreedy = epsilon_greedy(cfg, env)
    explore = LeanSequential(greedy, egreedy)  # (TensorDictSequential's result, less plumbing per call)
    eval_policy = GPIPolicy(qnet, dropout=False)  # the authors' q_net.eval() at evaluation
    dynamics = None
    if pd:
        model = ProbabilisticEnsemble(shape[0] + num_actions, shape[0] + k, ensemble_size=cfg.gpi_dynamics_ensemble,
                                      hidden=cfg.gpi_dynamics_hidden, num_elites=cfg.gpi_dynamics_elites,
                                      normalize_inputs=cfg.gpi_dynamics_normalize,
                                      max_logvar=cfg.gpi_dynamics_max_logvar).to(device)
        dynamics = DynamicsLoss(model, num_actions=num_actions)
    prefs = [t for t in transforms_of(env) if isinstance(t, PreferenceConditioning)]
    optimizers = {"qvalue": adam(loss.value_network_params.values(True, True), cfg.lr, fused=fused_choice(cfg))}
    return GPIAgent(cfg, loss, explore, eval_policy, optimizers, device=device, exploration_module=egreedy, gamma=gamma,
                    preference_transform=prefs[-1] if prefs else None, num_actions=num_actions, dynamics=dynamics)


def _evaluation_contexts(cfg) -> torch.Tensor | None:
    """``[E, c]``: the run evaluator's contexts in its order (:func:`~morl_trl.evaluation.suite_contexts`
    of :func:`~morl_trl.training.parts.evaluation_contexts`); ``None`` for a domain whose contexts are not vectors."""
    try:
        return suite_contexts(evaluation_contexts(cfg, domain_of(cfg.env_id)))[2]
    except (KeyError, ValueError, TypeError, NotImplementedError):  # (no registered context vectors)
        return None


def _make_continuous_gpi_agent(cfg, env, spec, *, gamma: float, device: torch.device) -> GPIAgent:
    """The authors' ``GPIPDContinuousAction``: a TD3-style actor and an ensemble of vector critics. Collection acts
    with the noisy actor for the row's ``w``; the CCS values and the corner weights use GPI over the support
    (single-env indexing), and so does the evaluation, with the conditioning weight of the authors' vectorised
    evaluator (``gpi_eval_conditioning="authors"``) or ``w_i`` (``"support"``)."""
    obs_dim, act_dim, k = obs_shape(env)[0], spec.shape[-1], num_objectives(env)
    actor = GPIActor(obs_dim, k, act_dim, low=spec.space.low, high=spec.space.high, hidden=cfg.hidden).to(device)
    critic = GPIVectorCritic(obs_dim, act_dim, k, hidden=cfg.hidden, num_nets=cfg.gpi_num_nets,
                             dropout=cfg.gpi_dropout, layer_norm=cfg.gpi_layer_norm).to(device)
    loss = GPIContinuousLoss(actor, critic, policy_noise=cfg.gpi_policy_noise, noise_clip=cfg.gpi_noise_clip,
                             min_priority=cfg.gpi_min_priority)
    loss.make_value_estimator(gamma=gamma)
    actor_m, critic_m = loss.actor_network.module, loss.qvalue_network.module
    explore = GPIContinuousPolicy(actor_m, noise=cfg.gpi_policy_noise, noise_clip=cfg.gpi_noise_clip)
    table = _evaluation_contexts(cfg) if cfg.gpi_eval_conditioning == "authors" else None
    eval_policy = GPIContinuousPolicy(actor_m, critic_m, gpi=True, context_table=table)
    gpi_policy = GPIContinuousPolicy(actor_m, critic_m, gpi=True)
    dynamics = None
    if cfg.algo == "gpi_pd":
        model = ProbabilisticEnsemble(obs_dim + act_dim, obs_dim + k, ensemble_size=cfg.gpi_dynamics_ensemble,
                                      hidden=cfg.gpi_dynamics_hidden, num_elites=cfg.gpi_dynamics_elites,
                                      normalize_inputs=cfg.gpi_dynamics_normalize,
                                      max_logvar=cfg.gpi_dynamics_max_logvar).to(device)
        dynamics = DynamicsLoss(model, num_actions=None)
    prefs = [t for t in transforms_of(env) if isinstance(t, PreferenceConditioning)]
    optimizers = {"qvalue": adam(loss.qvalue_network_params.values(True, True), cfg.lr, fused=fused_choice(cfg)),
                  "actor": adam(loss.actor_network_params.values(True, True), cfg.lr, fused=fused_choice(cfg))}
    return GPIAgent(cfg, loss, explore, eval_policy, optimizers, device=device, exploration_module=None, gamma=gamma,
                    preference_transform=prefs[-1] if prefs else None, num_actions=None, dynamics=dynamics,
                    gpi_policy=gpi_policy)


def train_gpi(run: Run) -> tuple[dict, GPIAgent]:
    """Train GPI-LS or GPI-PD (``run.cfg.algo``), discrete or continuous actions, in ``run`` (opened by
    :func:`~morl_trl.recipes.off_policy.run_training`: a new run or the continuation of one); returns
    ``(last evaluation summary, agent)``."""
    cfg = run.cfg
    device = torch.device(cfg.device)
    spec = run_domain(cfg)

    # 1. the env (everything is built before the run directory is touched: a failed start writes nothing).
    # Each sub-env draws its episode's preference from the support M (the agent sets it at each iteration).
    env = make_training_env(cfg, device)

    # 2. the modules (make_gpi_agent): the Q-networks (discrete) or actor + critics (continuous), the GPI
    # policies over M, the loss, Adam, GPI-PD's dynamics ensemble and model buffer, the linear support
    # and the first iteration's weight w and support M
    tune_malloc()  # (the allocator for training, as build_agent)
    agent = make_gpi_agent(cfg, env, gamma=run_discount(cfg, spec), device=device)
    reference = load_reference(cfg, spec)
    evaluator = make_evaluator(cfg, agent, spec, reference)  # (GPI over M for each evaluation weight)

    # 3. the replay buffer, a resumed run's state, the collector
    check_buffer_memory(cfg, env, device)
    buffer = make_replay_buffer(cfg, device)
    state = run.restore(buffer, map_location=device, env=env)
    if state is not None:  # (the model buffer is not checkpointed: GPI-PD refills it at its next rollout)
        load_agent_state(agent, state, run.resume_from, cfg.algo)  # networks, optimizers, the linear support, w, M, the iteration
        schedules(agent, run.frames)
    # (return_same_td: each batch is stored and logged before the next one is collected)
    collector = make_collector(cfg, env, agent.explore_policy, device, frames_done=run.frames, return_same_td=True)
    snapshot = checkpoint_snapshot(agent, env, collector, device)  # (what a checkpoint holds)

    # 4. the loop. One iteration = one batch (on_batch): store it; GPI-PD's model fit and rollouts when due; the
    # updates; the target copy; at the end of an iteration, the CCS; the ε schedule; then (run.step) evaluate and
    # checkpoint when due; then the next w and M. A checkpoint is the state at the end of a batch.
    with run.session(spec, reference, evaluator=evaluator, snapshot=snapshot, buffer=buffer, collector=collector,
                     notes=start_notes(cfg, run, spec, reference)):
        agent.begin_pending_iteration(buffer, collector)  # (a resumed run: an iteration that ended at its checkpoint begins, RNG restored)
        for batch in collector:  # (uniformly random actions for the first init_random_frames)
            frames = run.collected(batch)
            losses, updates = on_batch(agent, batch, buffer, frames)  # (a non-finite loss raises, counting those applied)
            collector.update_policy_weights_()
            run.step(losses, updates, epsilon=agent.epsilon)  # (an evaluation due now acts by GPI over this M)
            # the next w (a corner weight), M, the discrete PER priorities under w; the sub-envs reset to act with w
            agent.begin_pending_iteration(buffer, collector)
    return run.summary, agent


def update(agent: GPIAgent, buffer) -> TensorDictBase:
    """One gradient update of ``agent`` on a batch of :meth:`GPIAgent.sample_batch` (GPI-PD with model data:
    ``gpi_real_ratio`` real transitions, the rest imagined); returns its losses. The TD loss for ``w`` (GPI-PD:
    GPI over ``M`` in the target) writes the PER priorities, which go back to the real transitions of ``buffer``
    (the model buffer has none). Discrete: one Adam step of the Q-networks (``max_grad_norm``; the hard target
    copy is :func:`on_batch`'s). Continuous, the authors' TD3-style step: the critics every update, the actor
    every ``gpi_policy_delay`` updates against the critics just updated, each followed by Polyak averaging
    (``tau``, default 0.005) of its targets. A non-finite loss raises before any network moves."""
    cfg, loss, optimizers = agent.cfg, agent.loss, agent.optimizers
    batch, real = agent.sample_batch(buffer)
    out = loss(batch)
    if agent.continuous:
        tau = cfg.tau if cfg.tau is not None else 0.005
        check_finite({k: out[k] for k in ("loss_qvalue", "loss_actor")})  # both, before either network moves
        optimizer_step(out["loss_qvalue"], [optimizers["qvalue"]])
        polyak_(loss.target_qvalue_network_params, loss.qvalue_network_params, tau)
        if agent.continuous_updates % cfg.gpi_policy_delay == 0:
            optimizer_step(loss.actor_loss(), [optimizers["actor"]])  # (the record gives the delay, not this order)
            polyak_(loss.target_actor_network_params, loss.actor_network_params, tau)
        agent.continuous_updates += 1
    else:
        optimizer_step(out["loss_qvalue"], [optimizers["qvalue"]], max_grad_norm=agent.cfg.max_grad_norm,
                       losses={"loss_qvalue": out["loss_qvalue"]})
    if cfg.prioritized:
        if real is not batch:
            real.set("td_error", batch["td_error"][: real.shape[0]])
        buffer.update_tensordict_priority(real)
    return out.detach()


def on_batch(agent: GPIAgent, batch: TensorDictBase, buffer, frames: int) -> tuple[TensorDictBase | None, int]:
    """What :func:`train_gpi` does with one collected ``batch`` at ``frames`` frames: returns ``(last losses or
    None, updates done)``. Stores the batch; from ``init_random_frames`` on, GPI-PD's Dyna when due
    (:meth:`GPIAgent._dyna`), the updates (:func:`update`: 1 per frame, ``gpi_gradient_updates`` per frame from
    ``gpi_dynamics_rollout_starts`` on, the authors' discrete gating; continuous: ``gpi_gradient_updates``
    throughout; or ``updates_per_batch`` per batch) and, discrete, the hard target copy every
    ``target_update_period`` frames; at the end of an iteration (every ``gpi_iteration_frames`` frames) the CCS
    (:meth:`GPIAgent.end_iteration`), the next iteration left to :meth:`GPIAgent.begin_pending_iteration`
    after the run's evaluation; then the ε schedule (:func:`schedules`). A caller that never calls
    ``begin_pending_iteration`` has the pending iteration begin here first. A non-finite loss raises
    :class:`~morl_trl.training.optim.NonFiniteLossError` with ``updates_done``, the updates applied before it."""
    cfg = agent.cfg
    if agent.begin_pending:  # (train_gpi began it after its run.step: only other callers get here)
        agent.begin_iteration(buffer)
    prev, agent.frames = agent.frames, frames
    agent.store(buffer, batch)  # the entries the loss reads
    losses, updates = None, 0
    if frames >= cfg.init_random_frames:
        if cfg.gpi_update_weight == "episode":
            agent.use_episode_weight(batch)
        if agent.dynamics is not None:
            agent._dyna(buffer, prev, frames)  # the model fit on the whole real buffer; imagined transitions
        gated = not agent.continuous and frames < cfg.gpi_dynamics_rollout_starts
        updates = cfg.updates_per_batch or batch.numel() * (1 if gated else cfg.gpi_gradient_updates)
        for done in range(updates):
            with counted_update(done):  # (a non-finite loss: the run counts the updates applied before it)
                losses = update(agent, buffer)
        if not agent.continuous and frames // cfg.target_update_period > prev // cfg.target_update_period:
            agent.target_updater.step()  # the authors' hard copy every target_update_period frames
    if frames >= agent.iteration_end:
        while agent.iteration_end <= frames:
            agent.iteration_end += cfg.gpi_iteration_frames
        agent.end_iteration()  # GPI over M evaluated at each weight of M -> the linear support (CCS)
        agent.begin_pending = True
    schedules(agent, frames)
    return losses, updates


def schedules(agent: GPIAgent, frames: int) -> None:
    """GPI's frame-based schedule after ``frames`` frames: ε of the discrete exploration
    (:func:`~morl_trl.training.agent.epsilon`; the continuous actor's noise is fixed)."""
    if agent.exploration_module is not None:
        agent.exploration_module.eps.fill_(epsilon(agent.cfg, frames))
