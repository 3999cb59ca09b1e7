"""One MORL-Baselines 1.3.0 run of a parity case (run by run_parity.py inside MB's own venv).

    python mb_runner.py CASE SEEDS OUT_DIR      # SEEDS: 0,1,2 ; the finished ones are skipped

Trains MB's class with the case's hyperparameters through MB's own ``train()`` (its training
loop, ``log=False``: no wandb, no evaluation of its own) and evaluates it every ``eval_every``
frames with the shared evaluation (``common.evaluate_policy``: morl_trl's evaluator on the same
env, weights, discount and seed as our runs). The evaluation is hooked on the training env's
``step`` (on PGMORL's iterations, whose vector envs MB builds itself), so it happens at the same
frame counts as ours; training time is the wall time of ``train()`` minus these evaluations.
How an MB agent acts for an evaluation weight is what ours does for the same method (see
``_policy``): multi-policy methods act with the archived member of nearest weight, PCN with the
command of the nearest evaluation weight, MOSAC (one fixed weight, the case's ``weight``) with its own
``eval``, a sampled action whatever the evaluation weight (ours: the same weight, run_parity.fixed_preference).
"""

from __future__ import annotations

import contextlib
import inspect
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

import numpy as np  # noqa: E402

from common import (CASES, EVAL_EPISODES, EVAL_WEIGHTS, MB_VERSION, QEstimateLog, evaluate_paper_policy,  # noqa: E402
                    evaluate_policy, make_paper_gym_env, write_result)


def _row_act(act_one, space=None):
    """A policy for the evaluator from ``act_one(obs [..], w [k]) -> action`` applied row by row;
    continuous actions clipped to ``space`` (MB trains PGMORL's MOPPO behind gymnasium's ClipAction,
    and its eval() returns the unclipped Gaussian sample)."""
    import torch

    def policy(td):
        obs, w = td.get("observation").cpu().numpy(), td.get("preference").cpu().numpy()
        actions = np.stack([np.asarray(act_one(o, wi)) for o, wi in zip(obs, w)])
        if space is not None and hasattr(space, "low"):
            actions = np.clip(actions, space.low, space.high)
        return td.set("action", torch.as_tensor(actions).to(td.get("action").dtype if "action" in td.keys() else None))

    return policy


def _nearest(members, weights_of):
    """``act_one`` acting with the member whose weight is nearest (the first on ties), as ours."""
    ws = np.stack([np.asarray(weights_of(m), dtype=np.float64) for m in members])

    def act_one(o, w):
        m = members[int(np.argmin(((ws - np.asarray(w, dtype=np.float64)) ** 2).sum(-1)))]
        return m.eval(o, w) if hasattr(m, "eval") else m.wrapped.eval(o, w)

    return act_one


def _pcn_policy(agent, k: int):
    """MB's PCN acting through our PCN evaluation policy (same command choice and update rule):
    weight i of the energy set starts on the i-th of MB's ``_nlargest`` episodes' return and length."""
    import torch
    from torchrl.data import Bounded, Categorical

    from morl_trl.preferences import energy_weights
    from morl_trl.algorithms.pcn.recipe import PCNPolicy

    class _Net:
        def module(self, obs, desired, horizon):
            return agent.model(obs.float(), desired.float(), horizon.float())

    def commands():
        if not len(agent.experience_replay):  # before any episode (frame 0): ours' eval_commands, zeros and 1
            return torch.zeros(EVAL_WEIGHTS, k), torch.ones(EVAL_WEIGHTS)
        n = min(EVAL_WEIGHTS, len(agent.experience_replay))
        # MB's _nlargest re-prices every stored episode and re-heapifies the replay in place; MB's training
        # evicts the heap's smallest entry when it adds an episode, and gives the episodes added since its
        # last _choose_commands priority 1 (kept). The evaluation, hooked on env steps mid-round, would
        # re-price those too and change which episodes MB's training evicts: the replay is put back as it was.
        saved = list(agent.experience_replay)
        try:
            episodes = agent._nlargest(n)
        finally:
            agent.experience_replay[:] = saved
        returns = torch.as_tensor(np.float32([e[2][0].reward for e in episodes]))
        horizons = torch.as_tensor(np.float32([len(e[2]) for e in episodes]))
        reps = torch.arange(EVAL_WEIGHTS) % n
        return returns[reps], horizons[reps]

    space = agent.env.action_space
    spec = (Categorical(int(space.n)) if hasattr(space, "n")
            else Bounded(torch.as_tensor(space.low), torch.as_tensor(space.high), shape=space.shape))
    return PCNPolicy(_Net(), spec, mode="eval", weights=energy_weights(k, EVAL_WEIGHTS).float(), commands=commands,
                     max_return=[100.0] * k)  # MB's PCN.train default max_return


#: our registry name -> the MB class's (MORL/D SB+PSA is MB's MORLD with weight_adaptation_method="PSA")
MB_ALGO = {"morld_psa": "morld"}


def mb_algo(case: dict) -> str:
    """The MB method a case's ``algo`` (our registry name) runs."""
    return MB_ALGO.get(case["algo"], case["algo"])


def _policy(case: dict, agent, space):
    algo = mb_algo(case)
    if algo == "pcn":
        return _pcn_policy(agent, agent.reward_dim)
    if algo == "morld":  # MB's Pareto archive (filled after each exchange), else the population
        members = agent.archive.individuals or agent.population
        return _row_act(_nearest(members, lambda m: m.weights), space)
    if algo == "pgmorl":
        members = agent.archive.individuals or agent.agents
        return _row_act(_nearest(members, lambda m: m.np_weights), space)
    if algo in ("gpi_ls", "gpi_pd") and not len(getattr(agent, "weight_support", None) or []):  # (set by train())
        return _row_act(lambda o, w: _untrained_gpi_action(agent, o, w), space)
    return _row_act(lambda o, w: agent.eval(o, w), space)


def _batched_policy(case: dict, agent):
    """MB's agent acting for a whole batch of the evaluator's rows at once (a paper-domain case's suite is
    contexts x weights rows, each up to 1,000 steps): what its ``eval(obs, w)`` does row by row, on the batch.
    Envelope: ``max_action``, argmax_a w.Q(s, a, w) of its q_net; CAPQL: ``policy.get_action``, tanh(mean)."""
    import torch as th

    algo = case["algo"]
    if algo not in ("envelope", "capql"):
        raise SystemExit(f"no batched MB policy for {algo} (paper-domain cases: envelope, capql)")

    def policy(td):
        obs, w = td.get("observation").float(), td.get("preference").float()
        with th.no_grad():
            if algo == "envelope":
                q = agent.q_net(obs, w)  # [B, A, k]
                action = th.einsum("bk,bak->ba", w, q).argmax(-1)
            else:
                action = agent.policy.get_action(obs, w)
        if "action" in td.keys():
            action = action.to(td.get("action").dtype)
        return td.set("action", action)

    return policy


def _untrained_gpi_action(agent, obs, w):
    """MB's GPI agent before its first iteration: no weight support to take the GPI maximum over, so its
    Q-networks act greedily for ``w`` (``max_action``: the GPI maximum over the support ``{w}``)."""
    import torch as th

    for q_net in agent.q_nets:
        q_net.eval()
    action = agent.max_action(th.as_tensor(obs).float().to(agent.device), th.as_tensor(w).float().to(agent.device))
    for q_net in agent.q_nets:
        q_net.train()
    return action


#: the method of each MB multi-policy class that is the only place its Pareto archive changes (PGMORL: deep copies
#: of the members after the warm-up and every generation; MORL/D: after every exchange, morld.py's train())
ARCHIVE_UPDATES = {"pgmorl": "_PGMORL__eval_all_agents", "morld": "_MORLD__eval_all_policies"}


def evaluate_after_archive_updates(agent, evaluate, eval_every: int, method: str = ARCHIVE_UPDATES["pgmorl"],
                                   first: int = 0) -> None:
    """Hooks ``evaluate(frames)`` on ``method`` of an MB agent (:data:`ARCHIVE_UPDATES`: the only place its Pareto
    archive changes): after the call that finds ``global_step`` at or past the next multiple of ``eval_every``,
    the first being ``first`` (PGMORL and MORL/D: 0, their first call, before training)."""
    eval_all = getattr(agent, method)
    next_eval = [first]

    def eval_all_and_evaluate(*args, **kwargs):
        out = eval_all(*args, **kwargs)
        if agent.global_step >= next_eval[0]:
            evaluate(agent.global_step)
            next_eval[0] = agent.global_step + eval_every
        return out  # (MORL/D's evaluations feed its weight adaptation, PSA)

    setattr(agent, method, eval_all_and_evaluate)


@contextlib.contextmanager
def preserved_rng():
    """Python's, NumPy's and torch's global RNG states saved on entry and restored on exit. MB's agents draw
    from the global streams (``seed_everything``; NumPy's for exploration, torch's for minibatches and
    dropout), and building the evaluation's env and seeding it need not leave them alone: the shared
    evaluation, at frame 0 and every ``eval_every`` frames inside MB's loop, must not move MB's training
    off the trajectory it would follow unevaluated."""
    import random

    import torch

    state = random.getstate(), np.random.get_state(), torch.get_rng_state()
    try:
        yield
    finally:
        random.setstate(state[0])
        np.random.set_state(state[1])
        torch.set_rng_state(state[2])


def _call(fn, **kwargs):
    """``fn(**kwargs)`` keeping only the keyword arguments it takes (MB's train() signatures differ)."""
    names = inspect.signature(fn).parameters
    return fn(**{k: v for k, v in kwargs.items() if k in names})


def run(case_name: str, seed: int, out: Path) -> None:
    import mo_gymnasium as mo_gym
    import torch

    import morl_baselines  # noqa: F401
    from morl_baselines.common.evaluation import seed_everything

    from morl_trl.envs.foreign import MO_GYMNASIUM_REF_POINTS

    # MB 1.3.0's DST termination function (GPI-PD's model rollouts) imports mo_gymnasium.deep_sea_treasure,
    # which mo-gymnasium >= 1.1 moved to mo_gymnasium.envs.deep_sea_treasure: alias the old path
    import mo_gymnasium.envs.deep_sea_treasure as dst_pkg
    import mo_gymnasium.envs.deep_sea_treasure.deep_sea_treasure as dst_mod

    sys.modules.setdefault("mo_gymnasium.deep_sea_treasure", dst_pkg)
    sys.modules.setdefault("mo_gymnasium.deep_sea_treasure.deep_sea_treasure", dst_mod)

    case = CASES[case_name]
    paper = bool(case.get("paper"))
    seed_everything(seed)
    torch.set_num_threads(1)
    if paper:  # our domain through Gymnasium (morl_trl/<id>), under the paper's history (common.PAPER_CASES)
        env, eval_env = make_paper_gym_env(case), make_paper_gym_env(case)
    else:
        env, eval_env = mo_gym.make(case["env"]), mo_gym.make(case["env"])
    # MB 1.3.0's loops reset the env unseeded and sample random actions from its action space (PCN's warm-up
    # episodes, the agents' exploration), both seeded from OS entropy: two runs of one seed differed. Seeded
    # here once (what MB's own MOPPO does), so that a seed's run can be made again; the draws are as random.
    env.reset(seed=seed)
    env.action_space.seed(seed)
    if paper:  # (MB's train() takes one; its own evaluation never runs here: log=False)
        from morl_trl.envs.registry import domain_of

        ref_point = np.asarray(domain_of(case["env"]).hv_ref_point, dtype=np.float32)
    else:
        ref_point = np.asarray(MO_GYMNASIUM_REF_POINTS[case["env"]][0], dtype=np.float32)
    curve: list[dict] = []
    eval_s, eval_cpu = [0.0], [0.0]
    agent = None

    qlog = QEstimateLog() if case["algo"] == "envelope" else None

    def evaluate(frames: int) -> None:
        if qlog is not None:
            qlog.mark(frames)
        t, c = time.perf_counter(), time.process_time()
        with preserved_rng():  # (the evaluations leave MB's training trajectory as it would be without them)
            if paper:
                m = evaluate_paper_policy(_batched_policy(case, agent), case, seed)
            else:
                m = evaluate_policy(_policy(case, agent, eval_env.action_space), case["env"], case["gamma"], seed)
        curve.append(dict(frames=frames, **m))
        eval_s[0] += time.perf_counter() - t
        eval_cpu[0] += time.process_time() - c
        print(f"[mb {case_name} s{seed}] {frames} frames: "
              f"{ {k: v for k, v in m.items() if k != 'per_context'} }", flush=True)

    steps = [0]
    step = env.step

    # MORL/D acts with its Pareto archive, which changes only after each exchange: evaluated after that (below);
    # hooked on env steps, the evaluation at the end of a turn would act with the archive of the exchange before
    on_steps = mb_algo(case) != "morld"

    def counted_step(action):  # the shared evaluation every eval_every frames of MB's own loop
        result = step(action)
        steps[0] += 1
        if on_steps and steps[0] % case["eval_every"] == 0 and steps[0] <= case["frames"]:
            evaluate(steps[0])
        return result

    env.step = counted_step
    algo, kw = mb_algo(case), dict(gamma=case["gamma"], log=False, seed=seed, **case["mb"])
    if algo == "envelope":
        from morl_baselines.multi_policy.envelope.envelope import Envelope as cls
    elif algo in ("gpi_ls", "gpi_pd"):
        continuous = not hasattr(env.action_space, "n")
        if continuous:
            from morl_baselines.multi_policy.gpi_pd.gpi_pd_continuous_action import (
                GPILSContinuousAction, GPIPDContinuousAction)
            cls = GPILSContinuousAction if algo == "gpi_ls" else GPIPDContinuousAction
        else:
            from morl_baselines.multi_policy.gpi_pd.gpi_pd import GPILS, GPIPD
            cls = GPILS if algo == "gpi_ls" else GPIPD
        if isinstance(kw.get("dynamics_train_freq"), int):  # (MB's GPIPD takes a callable of the step)
            every = kw["dynamics_train_freq"]
            kw["dynamics_train_freq"] = lambda timestep: every
    elif algo == "pcn":
        from morl_baselines.multi_policy.pcn.pcn import PCN as cls
        kw["scaling_factor"] = np.asarray(kw["scaling_factor"], dtype=np.float32)
    elif algo == "capql":
        from morl_baselines.multi_policy.capql.capql import CAPQL as cls
    elif algo == "morld":
        from morl_baselines.multi_policy.morld.morld import MORLD as cls
    elif algo == "pgmorl":
        from morl_baselines.multi_policy.pgmorl.pgmorl import PGMORL as cls
    elif algo == "mosac":  # one policy for the case's fixed weight (MOSAC has no default: `weight` is required)
        from morl_baselines.single_policy.ser.mosac_continuous_action import MOSAC as cls
        kw["weights"] = np.asarray(case["weight"], dtype=np.float32)
    else:
        raise SystemExit(f"no MB runner for {algo}")
    if algo == "pgmorl":
        # MB builds its vector envs from the id. The evaluation acts with MB's Pareto archive, which
        # only changes in __eval_all_agents (deep copies of the members, after the warm-up and after
        # every generation, and once before training), so it is evaluated right after that call:
        # at frame 0 and after each iteration's update, as ours (whose archive takes the members when
        # each iteration's update is done). Hooked after __train_all_agents instead, as before, the
        # evaluation at frame F acted with the archive of the iteration before (one iteration stale).
        agent = cls(env_id=case["env"], origin=ref_point, **kw)
        evaluate_after_archive_updates(agent, evaluate, case["eval_every"], ARCHIVE_UPDATES["pgmorl"])
    else:
        agent = cls(env=env, **kw)
    if algo == "morld":
        # MB's MORL/D trains one member for exchange_every steps, then updates the others, evaluates every member
        # and fills its archive (__eval_all_policies), the one place the archive changes: each evaluation comes
        # right after the exchange that reaches its frame count, as ours (whose exchange precedes its evaluation
        # in the same batch). eval_every should be a multiple of exchange_every (CASES' morld cases are).
        # Frame 0 too comes after that method's first call (inside train(), before any update: the untrained
        # members archived), as ours' frame 0 follows its archive_initial_members (since d0bb3b8); before, MB's
        # frame 0 was evaluated before train(), with an empty archive (every member acting), while ours acted with
        # its archived (non-dominated) untrained members.
        evaluate_after_archive_updates(agent, evaluate, case["eval_every"], ARCHIVE_UPDATES["morld"], first=0)
    if qlog is not None:  # MB's update: q_net(b_obs, w) is its one forward with gradients (targets: no_grad)
        forward = agent.q_net.forward

        def logged_forward(obs, w):
            q = forward(obs, w)
            if torch.is_grad_enabled():
                qlog.record(w, q)
            return q

        agent.q_net.forward = logged_forward
    if algo not in ("pgmorl", "morld"):  # frame 0 as ours: the untrained agent, the same evaluator and weights
        evaluate(0)  # (PGMORL's and MORL/D's: hooked on their archive's first update, inside train(), before any update)
    t, e0, c, ec0 = time.perf_counter(), eval_s[0], time.process_time(), eval_cpu[0]
    _call(agent.train, total_timesteps=case["frames"], eval_env=eval_env, ref_point=ref_point,
          num_eval_weights_for_front=EVAL_WEIGHTS, eval_freq=10 ** 9, eval_mo_freq=10 ** 9, checkpoints=False,
          reset_num_timesteps=False, **case["mb_train"])
    train_s = time.perf_counter() - t - (eval_s[0] - e0)
    train_cpu = time.process_time() - c - (eval_cpu[0] - ec0)  # (this process's CPU time: one torch thread)
    frames = int(getattr(agent, "global_step", steps[0]) or steps[0])
    if not curve or curve[-1]["frames"] < min(frames, case["frames"]):
        evaluate(min(frames, case["frames"]))
    eval_s_total = eval_s[0]
    write_result(out, dict(case=case_name, lib="mb", seed=seed, version=f"morl-baselines {MB_VERSION}",
                           curve=curve, frames=frames, train_seconds=train_s, eval_seconds=eval_s_total,
                           train_fps=frames / train_s if train_s > 0 else None, train_cpu_seconds=train_cpu,
                           train_fps_cpu=frames / train_cpu if train_cpu > 0 else None, eval_episodes=EVAL_EPISODES,
                           **({} if qlog is None else {"q_check": qlog.result(case["env"], case["gamma"])})))


if __name__ == "__main__":  # several seeds in one process: the imports are paid once
    from common import result_path

    for _seed in [int(x) for x in sys.argv[2].split(",")]:
        _path = result_path(Path(sys.argv[3]), sys.argv[1], "mb", _seed)
        if not _path.exists():
            run(sys.argv[1], _seed, _path)
