"""MORL/D's round robin (algorithms/morld/recipe.py, the authors' MORLD.train: morld.py:421-431,559-567): one member
acts and learns per turn of exchange_every frames, the env is reset at each exchange, then every other
member gets morld_update_passes catch-up updates; an update steps only its members' parameters, Adam
moments, step counts and target critics."""

import pytest
import torch
from tensordict import TensorDict
from torchrl.collectors import Collector
from torchrl.data import Categorical, Composite, LazyTensorStorage, TensorDictReplayBuffer, Unbounded
from torchrl.envs import EnvBase, TransformedEnv
from torchrl.envs.utils import ExplorationType

from morl_trl._torchrl_compat import reset_collector
from morl_trl.recipes import TRAINING_ENV_BUILDERS, resolve_config
from morl_trl.recipes.fidelity import record
from morl_trl.algorithms.morld import recipe as morld
from morl_trl.algorithms.morld.recipe import make_morld_agent, round_robin_turns
from morl_trl.transforms import DiscountedVectorReturn

CPU = torch.device("cpu")
R = torch.tensor([[1.0, 0.0], [0.0, 1.0], [0.7, 0.7]])
EPISODE = 7


class Chain(EnvBase):
    """Episodes of 7 steps; the observation is (t, 1); three actions with the vector rewards ``R``.
    ``full_resets`` counts the resets of every sub-env at once (a collector's reset; TorchRL's
    automatic resets of finished episodes pass ``"_reset"``)."""

    def __init__(self, n=1):
        super().__init__(batch_size=[n])
        self.observation_spec = Composite(observation=Unbounded((n, 2)), shape=(n,))
        self.action_spec = Categorical(3, shape=(n,))
        self.reward_spec = Unbounded((n, 2))
        self.t = torch.zeros(n)
        self.full_resets = 0

    def _obs(self):
        return torch.stack([self.t, torch.ones_like(self.t)], -1)

    def _reset(self, td):
        mask = td.get("_reset").reshape(-1) if td is not None and "_reset" in td.keys() else None
        if mask is None:
            self.full_resets += 1
            self.t.zero_()
        else:
            self.t[mask] = 0
        n = self.batch_size[0]
        return TensorDict(observation=self._obs(), done=torch.zeros(n, 1, dtype=torch.bool),
                          terminated=torch.zeros(n, 1, dtype=torch.bool), batch_size=[n])

    def _step(self, td):
        self.t += 1
        n = self.batch_size[0]
        done = (self.t >= EPISODE).unsqueeze(-1)
        return TensorDict(observation=self._obs(), reward=R[td["action"]], done=done, terminated=done.clone(),
                          batch_size=[n])

    def _set_seed(self, seed):
        return seed


def _cfg(**kw):
    # LavaGrid's member settings (discrete MOSAC), a tiny population: 3 members, turns of 20 frames
    return resolve_config("morld", "MOLavaGridDR-v0", pop_size=3, num_envs=1, frames_per_batch=10, exchange_every=20,
                          init_random_frames=10, batch_size=8, hidden=(8,), target_update_period=5, frames=100,
                          morld_eval_episodes=0, seed=0, **kw)


def _member_state(agent, p):
    """Member ``p``'s parameters, target critics and Adam moments and counts (copies)."""
    loss = agent.loss
    out = {"actor." + ".".join(k): v[p].clone() for k, v in loss.actor_network_params.items(True, True)}
    out.update({"critic." + ".".join(k): v[:, p].clone() for k, v in loss.qvalue_network_params.items(True, True)})
    out.update({"target." + ".".join(k): v[:, p].clone()
                for k, v in loss.target_qvalue_network_params.items(True, True)})
    out["log_alpha"] = loss.log_alpha[p].clone()
    for name, opt in agent.optimizers.items():
        d = opt.param_groups[0]["member_dim"]
        for i, st in enumerate(opt.state.values()):
            out[f"{name}.{i}.step"] = st["step"][p].clone()
            for m in ("exp_avg", "exp_avg_sq"):
                out[f"{name}.{i}.{m}"] = st[m].select(d, p).clone()
    return out


def _same(a, b):
    return a.keys() == b.keys() and all(torch.equal(a[k], b[k]) for k in a)


def test_round_robin_turns_are_the_records_exchanges_per_member_on_every_pair():
    seen = 0
    for method in ("morld_sb", "morld_sb_psa"):
        for domain, table in record()[method].items():
            init, derived = table["init"], table["derived"]
            turns = round_robin_turns(table["train"]["total_timesteps"], init["exchange_every"], init["pop_size"])
            assert turns == derived["exchanges_per_member"]
            assert [t * init["exchange_every"] for t in turns] == derived["own_env_steps_per_member"]
            seen += 1
    assert seen == 10
    assert round_robin_turns(100, 20, 3) == [2, 2, 1]


def test_round_robin_trains_one_member_per_turn_resets_the_env_and_catches_the_others_up():
    torch.manual_seed(0)
    cfg = _cfg()
    base = Chain(1)
    env = TransformedEnv(base, DiscountedVectorReturn(0.9))
    agent = make_morld_agent(cfg, env, gamma=0.9, device=CPU)
    assert [type(o).__name__ for o in agent.optimizers.values()] == ["MemberAdam"] * 3
    buffer = TensorDictReplayBuffer(storage=LazyTensorStorage(1_000))
    collector = Collector(env, agent.explore_policy, frames_per_batch=10, total_frames=morld.frames_to_collect(cfg, 0),
                          init_random_frames=10, exploration_type=ExplorationType.RANDOM,
                          auto_register_policy_transforms=False)
    actives, first_obs, updates, frames = [], [], [], 0
    for batch in collector:
        frames += batch.numel()
        a = agent.active
        actives.append(a)
        first_obs.append(batch["observation"][0, 0, 0].item())
        before = [_member_state(agent, p) for p in range(3)]
        exchanges = agent.exchanges
        _, n = morld.on_batch(agent, batch, buffer, frames)
        updates.append(n)
        after = [_member_state(agent, p) for p in range(3)]
        for p in range(3):
            if p == a:
                assert _same(before[p], after[p]) == (frames <= 10), (frames, p)  # it learned (once updates start)
            elif agent.exchanges == exchanges:  # another member's turn: untouched, bit for bit
                assert _same(before[p], after[p]), (frames, p)
            else:  # the exchange's catch-up updates: stepped, and (discrete MOSAC) the targets copied at frame 20k
                assert not _same(before[p], after[p])
                for k in after[p]:
                    if k.startswith("target."):
                        assert torch.equal(after[p][k], after[p]["critic." + k[len("target."):]]), k
        if agent.env_reset_due():
            reset_collector(collector)
    collector.shutdown()
    # turns of 20 frames = 2 batches: members 0, 1, 2, 0, 1
    assert actives == [0, 0, 1, 1, 2, 2, 0, 0, 1, 1] and agent.active == 2 and agent.exchanges == 5
    # a reset at each exchange: every turn starts a fresh episode (t = 0) though episodes last 7 steps;
    # within a turn the episode goes on (batch 2 of each turn starts at t = 10 mod 7 = 3)
    assert base.full_resets == 1 + 5 and agent.env_resets == 5
    assert first_obs == [0.0, 3.0] * 5
    # own updates: one per frame past init_random_frames (the shared step index 11..19 in turn 1: 9, then 10
    # per batch); at each exchange (every 2nd batch) + 10 catch-up updates (one batched step of the 2 others)
    assert updates == [0, 9 + 10] + [10, 10 + 10] * 4
    own, catch_up = torch.tensor([9 + 20, 20 + 20, 20]), torch.tensor([3, 3, 4]) * 10
    assert agent.member_updates.tolist() == (own + catch_up).tolist() == [59, 70, 60]
    assert agent.member_frames.tolist() == [40, 40, 20]
    for opt in agent.optimizers.values():  # each member's own Adam count = the updates it received
        assert all(st["step"].tolist() == [59.0, 70.0, 60.0] for st in opt.state.values())
    # the state round-trips (a resumed run continues the same turn)
    other = make_morld_agent(cfg, TransformedEnv(Chain(1), DiscountedVectorReturn(0.9)), gamma=0.9, device=CPU)
    other.load_state_dict(agent.state_dict())
    assert (other.active, other.turn_frames, other.member_updates.tolist(), other.env_resets) == (2, 0, [59, 70, 60], 5)
    assert _same(_member_state(other, 1), _member_state(agent, 1))


def test_round_robin_clock_gives_the_authors_actor_turns_and_targets():
    torch.manual_seed(0)
    cfg = resolve_config("morld", "MOHopperDR-v5", pop_size=3, hidden=(8,), batch_size=4)
    env = TRAINING_ENV_BUILDERS["morld"](cfg, CPU)
    assert env.batch_size == torch.Size([1])  # the acting member's one env
    agent = make_morld_agent(cfg, env, gamma=0.99, device=CPU)
    # MOSAC: 2 actor steps when the shared global_step is even (mosac_continuous_action.py:460-482)
    turns = []
    for g in (10_001, 10_002, 20_000):
        agent.clock = g
        turns.append(morld.count_update(agent))
    assert turns == [False, True, True]
    # Polyak (tau 0.005) on the members of the mask only
    loss, upd = agent.loss, agent.target_updater
    targets = [t.clone() for t in upd.targets]
    with torch.no_grad():
        for s in upd.sources:
            s.add_(1.0)
    agent.members.copy_(torch.tensor([False, True, False]))
    upd.step()
    for s, t, t0 in zip(upd.sources, upd.targets, targets):
        assert torch.equal(t[:, [0, 2]], t0[:, [0, 2]])
        torch.testing.assert_close(t[:, 1], t0[:, 1] + 0.005 * (s[:, 1] - t0[:, 1]))
    assert loss.weights.shape == (3, 3)
    # the budget: whole turns (the authors' while global_step < total_timesteps)
    cfg.frames = 50_001
    assert morld.frames_to_collect(cfg, 0) == 60_000 and morld.frames_to_collect(cfg, 40_000) == 20_000


def test_round_robin_settings_are_checked():
    build = TRAINING_ENV_BUILDERS["morld"]
    with pytest.raises(ValueError, match="exchange_every=2000 must be a multiple of frames_per_batch=60"):
        build(resolve_config("morld", "MOLavaGridDR-v0", quick=True, frames_per_batch=60), CPU)
    with pytest.raises(ValueError, match="set updates_per_batch=0"):
        build(resolve_config("morld", "MOLavaGridDR-v0", quick=True, updates_per_batch=4), CPU)
    for schedule in ("round_robin", "concurrent"):  # (MORL/D's update is its own: nothing captures it)
        cfg = resolve_config("morld", "MOLavaGridDR-v0", quick=True, hidden=(8,), compile=True, morld_schedule=schedule)
        with pytest.raises(ValueError, match="set compile=false and cudagraphs=false"):
            make_morld_agent(cfg, build(cfg, CPU), gamma=0.99, device=CPU)
    with pytest.raises(ValueError, match="'morld_schedule'"):
        resolve_config("morld", "MOLavaGridDR-v0", morld_schedule="turns")


def test_the_fidelity_rows_of_the_round_robin_are_the_authors_and_concurrent_is_reported_as_a_difference():
    from morl_trl.recipes import fidelity

    settings = ("init.update_passes", "derived.exchanges_per_member", "derived.own_env_steps_per_member",
                "derived.updates_for_non_active_member_per_exchange", "derived.env_reset_at_each_exchange")
    by = {r.setting: r for r in fidelity.compare("morld", "MOHalfCheetahDR-v5")}
    assert [by[s].status for s in settings] == ["same"] * 5
    assert by["derived.exchanges_per_member"].ours == (84, 84, 83, 83, 83, 83)
    cfg = resolve_config("morld", "MOHalfCheetahDR-v5", morld_schedule="concurrent")
    by = {r.setting: r for r in fidelity.compare("morld", "MOHalfCheetahDR-v5", cfg)}
    assert by["derived.env_reset_at_each_exchange"].status == "differs: ours 'concurrent', the authors' 'round_robin'"
    assert by["derived.updates_for_non_active_member_per_exchange"].status == "differs: ours 0, the authors' 10"


@pytest.mark.parametrize("env_id", ["MOLavaGridDR-v0", "MOHopperDR-v5"])
def test_the_acting_members_update_computes_it_alone_with_the_masked_updates_result(env_id, single_thread):
    """Round robin: the acting member's own updates run on its slices alone (``[1, B]``); after two turns
    (members 0 and 1, each with the others' catch-up updates at its exchange) every member's parameters,
    target critics, temperature and Adam state equal those of the earlier implementation, which computed
    every member and masked the step (``slice_acting_member = False``), to float rounding, and the work per
    own update is one member's."""
    if env_id.startswith("MOHopper"):
        pytest.importorskip("mujoco")
    cfg = resolve_config("morld", env_id, pop_size=3, num_envs=1, frames_per_batch=10, exchange_every=20,
                         init_random_frames=0, batch_size=8, hidden=(16,), target_update_period=2, frames=40,
                         morld_eval_episodes=0, seed=0)
    env = TRAINING_ENV_BUILDERS["morld"](cfg, CPU)
    torch.manual_seed(1)
    td, batches = env.reset(), []
    for _ in range(4):  # the same four batches of 10 random frames for both
        batch = env.rollout(10, tensordict=td, auto_reset=False, break_when_any_done=False)
        td = batch[..., -1]["next"].clone()
        batches.append(batch)
    agents = []
    for sliced in (True, False):
        torch.manual_seed(0)
        agent = make_morld_agent(cfg, env, gamma=0.99, device=CPU)
        agent.slice_acting_member = sliced
        agents.append(agent)
    agents[1].load_state_dict(agents[0].state_dict())
    calls = []
    for agent in agents:
        torch.manual_seed(2)
        buffer = TensorDictReplayBuffer(storage=LazyTensorStorage(100))
        shapes = []
        agent.loss.qvalue_loss = (lambda f: lambda data: (shapes.append(tuple(data.shape)), f(data))[1])(
            agent.loss.qvalue_loss)
        for i, batch in enumerate(batches):
            morld.on_batch(agent, batch, buffer, 10 * (i + 1))
        calls.append(shapes)
    sliced, masked = agents
    # own updates at the shared steps 1..19 (member 0) and 20..39 (member 1), each [1, 8] sliced, [3, 8] masked;
    # 10 catch-up updates [3, 8] at each exchange
    assert calls[0] == [(1, 8)] * 19 + [(3, 8)] * 10 + [(1, 8)] * 20 + [(3, 8)] * 10
    assert calls[1] == [(3, 8)] * 59
    assert sliced.member_updates.tolist() == masked.member_updates.tolist() == [19 + 10, 10 + 20, 10 + 10]
    for p in range(3):
        a, b = _member_state(sliced, p), _member_state(masked, p)
        assert a.keys() == b.keys()
        for k in a:
            torch.testing.assert_close(a[k], b[k], rtol=1e-5, atol=1e-6, msg=lambda m, k=k, p=p: f"member {p} {k}: {m}")
