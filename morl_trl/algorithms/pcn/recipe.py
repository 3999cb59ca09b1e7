"""Pareto Conditioned Networks (Reymond et al. 2022): ``morl-trl train pcn``, read top to bottom.

PCN learns a policy conditioned on a *command* -- a desired return and a desired horizon --
by supervised learning on the steps of the best episodes of a replay of whole episodes
(:class:`~morl_trl.data.episode_replay.EpisodeReplay`, :class:`~morl_trl.objectives.pcn.PCNLoss`).
:func:`train_pcn` is the recipe (env -> modules and loss -> collector -> the loop), for discrete and
continuous actions; with its loss and the env's command transform
(:class:`~morl_trl.transforms.command.DesiredReturnConditioning`) it is everything PCN does per
frame. What it keeps between batches and checkpoints is a :class:`PCNAgent` (the network, the
replay, the unfinished episodes, the command, the round counters). The learning is two functions,
the one definition the loop runs and anything driving an agent batch by batch calls:
:func:`on_batch` (what the loop does with one collected batch) and :func:`update` (one supervised
update). Per batch:

1. the collected batch is cut into whole episodes per sub-env (an episode may span batches)
   which enter the episode replay with their returns-to-go (discount: the run's gamma;
   :meth:`PCNAgent.store_episodes`);
2. the first ``pcn_er_episodes`` episodes act uniformly at random (the authors' experience
   replay warm-up);
3. then, and after every further ``pcn_step_episodes`` episodes, a round: ``pcn_model_updates``
   supervised updates on ``batch_size`` steps (:func:`update`), and a new command for the
   episodes that start next: a random non-dominated return among the ``pcn_er_episodes`` best, plus
   ``U(0, std)`` on one objective, horizon = its length - 2
   (:meth:`~morl_trl.data.episode_replay.EpisodeReplay.choose_command`).

While acting the command is updated per step (``desired_return = min(desired_return - r,
max_return)`` with the undiscounted reward ``r``, ``horizon = max(horizon - 1, 1)``,
:class:`~morl_trl.transforms.command.DesiredReturnConditioning`); discrete actions are sampled
from the policy, continuous ones get Gaussian noise (``pcn_noise``) drawn per action dimension,
as the authors' ``np.random.normal(0, noise, size)`` (SPEC §6).

Evaluation (SPEC §2, §6): the ``n`` evaluation weights get the returns and lengths of the
``min(n, E)`` best replay episodes, repeated to ``n``; weight ``i`` (the row of the energy weight
set nearest to the preference the evaluator gives) acts greedily, starting each episode on
command ``i`` and updating it after every step by the same rule as in training (the authors'
evaluator: ``set_desired_return_and_horizon``, then ``eval`` with the vector reward, restored
afterwards). The network's widths are the run's ``hidden`` (the authors'
``net_arch``).

Example:
    >>> from morl_trl.recipes import resolve_config
    >>> cfg = resolve_config("pcn", "MOLavaGridDR-v0", quick=True, num_envs=2)
    >>> env = make_pcn_training_env(cfg, torch.device("cpu"))
    >>> agent = make_pcn_agent(cfg, env, gamma=0.995, device=torch.device("cpu"))
    >>> agent.explore_policy(env.reset())["action"].shape
    torch.Size([2])

    Training (``morl-trl train pcn MOLavaGridDR-v0 --quick`` runs the same):

    >>> from morl_trl.recipes import train
    >>> summary = train(resolve_config("pcn", "MOLavaGridDR-v0", quick=True))  # doctest: +SKIP
"""

from __future__ import annotations

import torch
from tensordict import TensorDict, TensorDictBase
from tensordict.nn import TensorDictModuleBase
from torchrl.envs import ClipTransform

from morl_trl.data.episode_replay import EpisodeReplay
from morl_trl.envs import domain_of, make_env
from morl_trl.objectives.pcn import PCNLoss, make_pcn_network
from morl_trl.preferences import energy_weights
from morl_trl.training.agent import Agent, action_spec, counted_update, is_discrete, num_objectives, obs_shape
from morl_trl.training.allocator import tune_malloc
from morl_trl.training.optim import adam, fused_choice, optimizer_step
from morl_trl.training.parts import (
    load_agent_state,
    checkpoint_snapshot,
    load_reference,
    make_collector,
    make_evaluator,
    run_discount,
    run_domain,
    start_notes,
)
from morl_trl.runs.run import Run
from morl_trl.transforms import DiscountedVectorReturn, compose_policy_env
from morl_trl.transforms.command import DesiredReturnConditioning

__all__ = ["PCNAgent", "PCNPolicy", "make_pcn_agent", "make_pcn_training_env", "on_batch", "train_pcn", "update"]


def _gamma(cfg) -> float:
    return cfg.gamma if cfg.gamma is not None else domain_of(cfg.env_id).gamma


def _max_return(cfg, k: int) -> list[float]:
    mr = list(cfg.pcn_max_return) if cfg.pcn_max_return is not None else [100.0] * k
    if len(mr) != k:
        raise ValueError(f"config key 'pcn_max_return' is {list(cfg.pcn_max_return)}; valid: {k} numbers "
                         f"(one per objective of {cfg.env_id}) or null")
    return [float(x) for x in mr]


def make_pcn_training_env(cfg, device: torch.device):
    """``make_env(cfg.env_id)`` + the policy's history + the command
    (:class:`~morl_trl.transforms.command.DesiredReturnConditioning`) + vector returns (for the logs)."""
    env = compose_policy_env(make_env(cfg.env_id, num_envs=cfg.num_envs, device=device, seed=cfg.seed),
                             history_len=cfg.history_len)
    k = num_objectives(env)
    spec = action_spec(env)
    if not is_discrete(spec):  # MuJoCo clamps the controls to their range: the env gets them clipped, PCN learns the sample
        env.append_transform(ClipTransform(in_keys_inv=["action"], out_keys_inv=["action"],
                                           low=float(spec.space.low.min()), high=float(spec.space.high.max())))
    env.append_transform(DesiredReturnConditioning(k, max_return=_max_return(cfg, k)))
    env.append_transform(DiscountedVectorReturn(_gamma(cfg)))
    return env


class PCNPolicy(TensorDictModuleBase):
    """Acts with a PCN network on ``observation`` and a command.

    ``mode="explore"``: the command is read from the TensorDict (``desired_return``,
    ``desired_horizon``); discrete actions are sampled, continuous ones get ``N(0, noise)`` noise
    per action dimension; ``random_actions = True`` samples the action spec instead (the
    warm-up). ``mode="eval"``: greedy actions; each episode starts on the command of the
    evaluation weight nearest to ``"preference"`` (``commands()`` gives ``(returns [n, k],
    horizons [n])`` for the ``n`` rows of ``weights``), which is then updated after every step:
    ``desired_return = min(desired_return - r, max_return)``, ``horizon = max(horizon - 1, 1)``,
    ``r`` the step's vector reward read as the change of the running undiscounted return
    ``return_key``; an episode starts where the running discount ``discount_key`` is 1 (the
    evaluator's keys; without them the command stays the starting one). The command acted on is
    written to ``desired_return`` / ``desired_horizon``.
    """

    def __init__(self, network, spec, *, mode: str, noise: float = 0.1, weights=None, commands=None,
                 max_return=None, return_key: str = "eval_episode_return",
                 discount_key: str = "eval_episode_discount") -> None:
        super().__init__()
        if mode not in ("explore", "eval"):
            raise ValueError(f"mode must be 'explore' or 'eval', got {mode!r}")
        self.network, self.action_spec_, self.mode, self.noise = network, spec, mode, float(noise)
        self.discrete = is_discrete(spec)
        self.random_actions = False
        self.in_keys = ["observation"] + (["desired_return", "desired_horizon"] if mode == "explore" else ["preference"])
        self.out_keys = ["action"]
        if mode == "eval":
            self.register_buffer("weights", torch.as_tensor(weights, dtype=torch.float32))
            self._commands = commands
            self.stale = True
            self._cache = None
            self.max_return = None if max_return is None else torch.as_tensor(max_return, dtype=torch.float32)
            self.return_key, self.discount_key = return_key, discount_key
            self._running = None  # (desired [*B, k], horizon [*B, 1], running return [*B, k]) of the episodes

    def _start_command(self, td: TensorDictBase):
        if self.stale or self._cache is None:
            returns, horizons = self._commands()
            self._cache = (returns, horizons)
            self.stale = False
        returns, horizons = self._cache
        w = td.get("preference").to(self.weights.device, torch.float32)
        idx = torch.cdist(w.reshape(-1, w.shape[-1]), self.weights).argmin(-1).reshape(w.shape[:-1])
        dev = td.device if td.device is not None else w.device
        return returns[idx].to(dev), horizons[idx].unsqueeze(-1).to(dev)

    def _eval_command(self, td: TensorDictBase):
        start_r, start_h = self._start_command(td)
        ret, disc = td.get(self.return_key, None), td.get(self.discount_key, None)
        if ret is None or disc is None:  # (no episode bookkeeping: the starting command)
            return start_r, start_h
        ret = ret.to(start_r.device, torch.float32)
        start = (disc.to(start_r.device) == 1).reshape(*start_r.shape[:-1], 1)
        if self._running is None or self._running[0].shape != start_r.shape:
            start = torch.ones_like(start)
            self._running = (start_r, start_h, ret)
        desired, horizon, before = self._running
        reward = ret - before  # the vector reward of the step just taken
        mr = self.max_return.to(ret.device) if self.max_return is not None else torch.full_like(ret, torch.inf)
        desired = torch.where(start, start_r, torch.minimum(desired - reward, mr))
        horizon = torch.where(start, start_h, (horizon - 1).clamp_min(1.0))
        self._running = (desired, horizon, ret)
        return desired, horizon

    def forward(self, td: TensorDictBase) -> TensorDictBase:
        if self.random_actions:
            return td.set("action", self.action_spec_.rand(td.batch_size))
        if self.mode == "eval":
            desired, horizon = self._eval_command(td)
            td.set("desired_return", desired)
            td.set("desired_horizon", horizon)
        else:
            desired, horizon = td.get("desired_return"), td.get("desired_horizon")
        out = self.network.module(td.get("observation"), desired, horizon)
        if self.discrete:
            if self.mode == "eval":
                action = out.argmax(-1)
            else:
                action = torch.distributions.Categorical(logits=out).sample()
            return td.set("action", action.to(self.action_spec_.dtype))
        if self.mode == "explore":
            out = out + self.noise * torch.randn_like(out)  # per dimension, as the authors (SPEC §6)
        else:  # the env's bounds (the training env clips the explored actions the same way)
            out = torch.maximum(torch.minimum(out, self.action_spec_.space.high.to(out.device)),
                                self.action_spec_.space.low.to(out.device))
        return td.set("action", out.to(self.action_spec_.dtype))


class PCNAgent(Agent):
    """What PCN keeps between batches and checkpoints (see the module): the network and Adam, the episode replay,
    the unfinished episodes, the command transform, the warm-up and round counters, its random generator."""

    def __init__(self, cfg, loss, explore_policy, eval_policy, optimizer, replay: EpisodeReplay, command, *,
                 device, max_return) -> None:
        super().__init__(cfg, loss, explore_policy, eval_policy, {"policy": optimizer}, None, device=device)
        self.replay, self.command = replay, command
        self.generator = torch.Generator().manual_seed(cfg.seed + 7)
        self.max_return = torch.as_tensor(max_return)
        self.episodes = 0  # episodes added to the replay
        self.next_round = cfg.pcn_er_episodes  # episodes after which the next round of updates runs
        self.rounds = 0
        self._pending: dict[int, dict[str, torch.Tensor]] = {}  # sub-env -> the steps of its unfinished episode
        self.explore_policy.random_actions = True

    # ------------------------------------------------------------------ episodes and commands
    def store_episodes(self, batch: TensorDictBase, frames: int) -> int:
        """Cut ``batch`` ``[N, T]`` into episodes per sub-env and add the finished ones to the replay, with
        their returns-to-go (an episode may span batches: its first steps wait in the agent until it ends).
        Returns how many episodes were added."""
        b = batch.reshape(-1, batch.shape[-1]) if batch.ndim > 1 else batch.unsqueeze(0)
        obs, act = b.get("observation").cpu(), b.get("action").cpu()
        rew, done = b.get(("next", "reward")).cpu(), b.get(("next", "done")).reshape(b.shape).cpu()
        added = 0
        for i in range(b.shape[0]):
            start = 0
            ends = done[i].nonzero().flatten().tolist()
            for end in ends + [None]:
                stop = b.shape[1] if end is None else end + 1
                piece = {"observation": obs[i, start:stop], "action": act[i, start:stop], "reward": rew[i, start:stop]}
                prev = self._pending.pop(i, None)
                if prev is not None:
                    piece = {k: torch.cat([prev[k], v]) for k, v in piece.items()}
                if end is None:
                    if piece["reward"].shape[0]:
                        # (kept past this batch: slices of it are copied, since the collector writes the next batch
                        # into the same memory, return_same_td; the replay copies what it adds)
                        self._pending[i] = piece if prev is not None else {k: v.clone() for k, v in piece.items()}
                else:
                    self.replay.add(piece["observation"], piece["action"], piece["reward"], step=frames)
                    added += 1
                start = stop
        self.episodes += added
        return added

    def eval_commands(self, n: int):
        """``(returns [n, k], horizons [n])`` of the evaluation (zeros and 1 before any episode)."""
        if not len(self.replay):
            k = self.max_return.numel()
            return torch.zeros(n, k), torch.ones(n)
        return self.replay.top_commands(n)

    # ------------------------------------------------------------------ state
    def state_dict(self) -> dict:
        state = super().state_dict()
        state.update(replay=self.replay.state_dict(), pending=dict(self._pending), episodes=self.episodes,
                     next_round=self.next_round, rounds=self.rounds, generator=self.generator.get_state(),
                     command=(self.command.command_return.clone(), self.command.command_horizon.clone()),
                     random_actions=self.explore_policy.random_actions)
        return state

    def load_state_dict(self, state: dict) -> None:
        super().load_state_dict(state)
        self.replay.load_state_dict(state["replay"])
        self._pending = dict(state["pending"])
        self.episodes, self.next_round, self.rounds = state["episodes"], state["next_round"], state["rounds"]
        self.generator.set_state(state["generator"])
        self.command.set_command(state["command"][0], float(state["command"][1]))
        self.explore_policy.random_actions = state["random_actions"]
        self.eval_policy.stale = True


def _command_transform(env) -> DesiredReturnConditioning:
    from morl_trl.runs.env_state import transforms_of

    for t in transforms_of(env):
        if isinstance(t, DesiredReturnConditioning):
            return t
    raise ValueError("the PCN agent needs a training env with DesiredReturnConditioning (make_pcn_training_env)")


def make_pcn_agent(cfg, env, *, gamma: float, device: torch.device) -> PCNAgent:
    """The PCN :class:`PCNAgent` of ``cfg`` for ``env`` (:func:`make_pcn_training_env`); discrete or continuous actions."""
    spec = action_spec(env)
    k = num_objectives(env)
    discrete = is_discrete(spec)
    scale = list(cfg.pcn_scaling_factor) if cfg.pcn_scaling_factor is not None else [0.1] * (k + 1)
    if len(scale) != k + 1:
        raise ValueError(f"config key 'pcn_scaling_factor' is {scale}; valid: {k + 1} numbers (the desired return's "
                         f"{k} and the horizon's) or null")
    shape = obs_shape(env)
    obs_dim = shape[0] if len(shape) == 1 else shape
    action_dim = spec.space.n if discrete else int(spec.shape[-1])
    widths = tuple(cfg.hidden)  # the authors' net_arch
    net = make_pcn_network(obs_dim, action_dim, k, scale, widths, discrete=discrete).to(device)
    loss = PCNLoss(net)
    optimizer = adam(loss.parameters(), cfg.lr, fused=fused_choice(cfg))
    explore = PCNPolicy(net, spec, mode="explore", noise=cfg.pcn_noise)
    holder: dict = {}
    evalp = PCNPolicy(net, spec, mode="eval", weights=energy_weights(k, cfg.eval_weights).float(),
                      commands=lambda: holder["agent"].eval_commands(cfg.eval_weights), max_return=_max_return(cfg, k))
    replay = EpisodeReplay(cfg.pcn_buffer_episodes, gamma)
    agent = PCNAgent(cfg, loss, explore, evalp, optimizer, replay, _command_transform(env), device=device,
                     max_return=_max_return(cfg, k))
    holder["agent"] = agent
    return agent


def update(agent: PCNAgent, buffer=None) -> TensorDictBase:
    """One supervised update of ``agent`` on ``batch_size`` steps of its episode replay (``agent.replay``;
    ``buffer`` is unused: PCN has no transition buffer, the argument keeps the call alike for every algorithm).
    Returns the losses; a non-finite loss raises :class:`~morl_trl.training.optim.NonFiniteLossError` before anything changes."""
    # an episode uniformly, then a step of it uniformly: (obs, action, return-to-go, horizon left)
    obs, action, ret, horizon = agent.replay.sample(agent.cfg.batch_size, generator=agent.generator)
    obs, action, ret, horizon = (t.to(agent.device) for t in (obs, action, ret, horizon))
    out = agent.loss.losses_of(obs, action, ret, horizon)  # the action taken given (obs, return-to-go, horizon)
    if out is None:  # (a custom network: the loss's TensorDict path)
        td = TensorDict({"observation": obs, "action": action, "desired_return": ret, "desired_horizon": horizon},
                        [obs.shape[0]], device=agent.device)
        out = agent.loss(td)
    optimizer_step(out["loss_pcn"], [agent.optimizers["policy"]], losses={"loss_pcn": out["loss_pcn"]})
    return out.detach()


def on_batch(agent: PCNAgent, batch: TensorDictBase, buffer, frames: int) -> tuple[TensorDictBase | None, int]:
    """What :func:`train_pcn` does with one collected ``batch`` after ``frames`` frames; returns ``(last losses or
    None, updates done)``. ``buffer`` is unused (the episodes go to ``agent.replay``).

    Its finished episodes enter the replay with their returns-to-go (:meth:`PCNAgent.store_episodes`); once the
    warm-up's ``pcn_er_episodes`` episodes are in, and after every further ``pcn_step_episodes``, a round:
    ``pcn_model_updates`` :func:`update` calls, then the command of the episodes that start next (a random
    non-dominated return among the ``pcn_er_episodes`` best, plus ``U(0, std)`` on one objective; horizon = its
    length - 2) and the end of the warm-up's random actions. A
    :class:`~morl_trl.training.optim.NonFiniteLossError` carries ``updates_done``: the updates of this batch
    applied before it."""
    cfg = agent.cfg
    agent.store_episodes(batch, frames)  # the finished episodes -> the replay, with their returns-to-go
    losses, updates = None, 0
    while agent.episodes >= agent.next_round:  # a round
        for done in range(cfg.pcn_model_updates):
            with counted_update(updates + done):  # (a non-finite loss: the run counts the updates applied before it)
                losses = update(agent)
        updates += cfg.pcn_model_updates
        desired, horizon = agent.replay.choose_command(cfg.pcn_er_episodes, generator=agent.generator)
        agent.command.set_command(desired, horizon)
        agent.explore_policy.random_actions = False  # (the warm-up is over)
        agent.rounds += 1
        agent.next_round = agent.episodes + cfg.pcn_step_episodes
    agent.eval_policy.stale = True  # (the evaluation's commands: the replay's best episodes, read again)
    return losses, updates


def train_pcn(run: Run) -> tuple[dict, PCNAgent]:
    """Train PCN, discrete or continuous actions, in ``run`` (opened by
    :func:`~morl_trl.recipes.off_policy.run_training`: a new run or the continuation of one); returns
    ``(last evaluation summary, agent)``."""
    cfg = run.cfg
    device = torch.device(cfg.device)
    spec = run_domain(cfg)

    # 1. the env (everything is built before the run directory is touched: a failed start writes nothing):
    # the DR env + the policy's history + the command (desired return, horizon) per sub-env + vector returns
    env = make_pcn_training_env(cfg, device)

    # 2. the modules (make_pcn_agent): the command-conditioned network, the exploring policy (random actions
    # during the warm-up) and the evaluation's, the loss, Adam, the episode replay
    tune_malloc()  # (the allocator for training, as build_agent)
    agent = make_pcn_agent(cfg, env, gamma=run_discount(cfg, spec), device=device)
    reference = load_reference(cfg, spec)
    evaluator = make_evaluator(cfg, agent, spec, reference)  # (weight i acts on the i-th best episode's command)

    # 3. a resumed run's state (the replay, the unfinished episodes, the command: all in the agent's state;
    # PCN has no transition buffer), the collector
    state = run.restore(None, map_location=device, env=env)
    if state is not None:
        load_agent_state(agent, state, run.resume_from, cfg.algo)
    # (return_same_td: each batch's episodes are copied out and logged before the next one is collected)
    collector = make_collector(cfg, env, agent.explore_policy, device, frames_done=run.frames, return_same_td=True)

    snapshot = checkpoint_snapshot(agent, env, collector, device)  # (what a checkpoint holds)

    # 4. the loop. One iteration = one batch: store its finished episodes; once the warm-up's pcn_er_episodes
    # episodes are in, and after every further pcn_step_episodes, a round (the updates, then a new command);
    # then (run.step) evaluate and checkpoint when due. A checkpoint is the state at the end of a batch.
    with run.session(spec, reference, evaluator=evaluator, snapshot=snapshot, collector=collector,
                     notes=start_notes(cfg, run, spec, reference)):
        for batch in collector:  # (the command is updated per step by the env's DesiredReturnConditioning)
            frames = run.collected(batch)
            losses, updates = on_batch(agent, batch, None, frames)  # store the episodes, the rounds due
            collector.update_policy_weights_()
            run.step(losses, updates)
    return run.summary, agent
