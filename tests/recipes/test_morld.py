"""MORL/D (morld, morld_psa) and the SAC baseline: the authors' settings, PSA, the archive, learning."""

import importlib.util

import pytest
import torch
from tensordict import TensorDict
from torchrl.collectors import Collector
from torchrl.data import Categorical, Composite, LazyTensorStorage, TensorDictReplayBuffer, Unbounded
from torchrl.envs import EnvBase, TransformedEnv
from torchrl.envs.utils import ExplorationType, set_exploration_type

from morl_trl.preferences import energy_weights
from morl_trl.recipes import ALGORITHMS, AGENT_BUILDERS, TRAINING_ENV_BUILDERS, resolve_config, train
from morl_trl.algorithms.morld import recipe as morld
from morl_trl.algorithms.morld.recipe import MORLDAgent, ParetoArchive, make_morld_agent, psa_weights
from morl_trl.transforms import DiscountedVectorReturn
from morl_trl.runs import latest_checkpoint, load_checkpoint

CPU = torch.device("cpu")


# ---------------------------------------------------------------------- the authors' settings (SPEC §4)
@pytest.mark.parametrize("algo", ["morld", "morld_psa"])
def test_morld_config_is_spec_section_4(algo):
    c = {d: resolve_config(algo, d) for d in ("MOHopperDR-v5", "MOHalfCheetahDR-v5", "MOHumanoidDR-v5",
                                              "MOLunarLanderDR-v0", "MOLavaGridDR-v0")}
    assert {d: (x.pop_size, x.exchange_every, x.init_random_frames, x.batch_size) for d, x in c.items()} == {
        "MOHopperDR-v5": (6, 20_000, 10_000, 256), "MOHalfCheetahDR-v5": (6, 10_000, 25_000, 256),
        "MOHumanoidDR-v5": (6, 20_000, 5_000, 256), "MOLunarLanderDR-v0": (6, 20_000, 20_000, 128),
        "MOLavaGridDR-v0": (5, 10_000, 20_000, 128)}
    assert all(x.tau == 0.005 and x.eval_exploration == "random" and not x.prioritized for x in
               (c["MOHopperDR-v5"], c["MOHalfCheetahDR-v5"], c["MOHumanoidDR-v5"]))
    lander, grid = c["MOLunarLanderDR-v0"], c["MOLavaGridDR-v0"]
    # discrete (hyperparameters.toml [morld_sb.*.policy_args]): the scripts' update_frequency 1, so hard
    # targets every 2000 / 200 frames = updates; Adam eps 1e-4 and one lr 3e-4
    assert (lander.tau, lander.target_update_period, lander.update_frequency, lander.target_entropy_scale) == \
        (None, 2000, 1, 0.3)
    assert (grid.target_update_period, grid.update_frequency) == (200, 1)
    assert (lander.q_lr, lander.alpha_lr, lander.adam_eps) == (3e-4, 3e-4, 1e-4)
    # continuous members: critics and temperature 1e-3, temperature tuned from 1.0
    assert (c["MOHopperDR-v5"].q_lr, c["MOHopperDR-v5"].alpha_lr, c["MOHopperDR-v5"].alpha) == (1e-3, 1e-3, 1.0)
    assert c["MOHopperDR-v5"].weight_adaptation == ("psa" if algo == "morld_psa" else "none")
    assert c["MOHopperDR-v5"].history_len == 2 and grid.history_len == 0
    assert AGENT_BUILDERS[algo] is make_morld_agent and algo in TRAINING_ENV_BUILDERS


def test_sac_config_is_spec_section_4():
    hop, lander, grid = (resolve_config("sac", d) for d in ("MOHopperDR-v5", "MOLunarLanderDR-v0", "MOLavaGridDR-v0"))
    # hyperparameters.toml [sac.*]: alpha tuned from 1.0 (autotune), learning_starts 1000 on MuJoCo;
    # discrete: one update every 4 frames after 20k random frames, targets every 2000 / 200 frames
    assert (hop.alpha, hop.learn_alpha, hop.batch_size, hop.tau, hop.init_random_frames) == (1.0, True, 256, 0.005, 1000)
    assert (hop.q_lr, hop.alpha_lr, hop.lr) == (1e-3, 1e-3, 3e-4)
    assert (lander.batch_size, lander.update_frequency, lander.init_random_frames) == (128, 4, 20_000)
    assert (lander.target_update_period * lander.update_frequency, lander.target_entropy_scale) == (2000, 0.3)
    assert grid.target_update_period * grid.update_frequency == 200
    assert "sac" in ALGORITHMS


def test_quick_morld_is_the_round_robin_and_concurrent_runs_p_times_num_envs_sub_envs():
    cfg = resolve_config("morld", "MOLavaGridDR-v0", quick=True)
    assert (cfg.pop_size, cfg.num_envs, cfg.frames_per_batch, cfg.updates_per_batch, cfg.exchange_every,
            cfg.morld_schedule, cfg.morld_update_passes) == (5, 1, 50, 0, 2000, "round_robin", 10)
    concurrent = resolve_config("morld", "MOLavaGridDR-v0", quick=True, morld_schedule="concurrent", num_envs=2,
                                frames_per_batch=60)
    assert TRAINING_ENV_BUILDERS["morld"](concurrent, CPU).batch_size == torch.Size([10])
    with pytest.raises(ValueError, match=r"multiple of pop_size \* num_envs = 5 \* 7 = 35"):
        TRAINING_ENV_BUILDERS["morld"](resolve_config("morld", "MOLavaGridDR-v0", quick=True, num_envs=7,
                                                      morld_schedule="concurrent"), CPU)
    with pytest.raises(ValueError, match="'weight_adaptation'"):
        resolve_config("morld", "MOLavaGridDR-v0", weight_adaptation="annealing")


# ---------------------------------------------------------------------- PSA and the archive
def test_psa_moves_each_weight_away_from_its_nearest_archived_neighbour():
    w = torch.tensor([[0.5, 0.5], [0.2, 0.8], [0.9, 0.1]], dtype=torch.float64)
    evals = torch.tensor([[2.0, 2.0], [1.0, 3.0], [float("nan"), 0.0]], dtype=torch.float64)
    archive = torch.tensor([[2.0, 2.0], [3.0, 1.0], [1.0, 3.0]], dtype=torch.float64)
    new = psa_weights(w, evals, archive, 0.1)
    # member 0: nearest other point (3, 1) (tie with (1, 3): the first) -> objective 0 worse, objective 1 better
    expect0 = torch.tensor([0.5 / 1.1, 0.5 * 1.1], dtype=torch.float64)
    # member 1: itself skipped (distance 0 <= 0.01), nearest (2, 2): objective 0 worse, objective 1 better
    expect1 = torch.tensor([0.2 / 1.1, 0.8 * 1.1], dtype=torch.float64)
    torch.testing.assert_close(new[0], expect0 / expect0.sum())
    torch.testing.assert_close(new[1], expect1 / expect1.sum())
    torch.testing.assert_close(new[2], w[2])  # not evaluated: unchanged


def test_archive_keeps_the_non_dominated_and_their_policies():
    a = ParetoArchive()
    a.add(torch.tensor([[1.0, 1.0], [2.0, 0.0]]), [{"id": 0}, {"id": 1}])
    a.add(torch.tensor([[1.5, 1.5], [2.0, 0.0]]), [{"id": 2}, {"id": 3}])
    assert a.evaluations.tolist() == [[2.0, 0.0], [1.5, 1.5]]
    assert [i["id"] for i in a.individuals] == [1, 2]


# ---------------------------------------------------------------------- a bandit the population must cover
R = torch.tensor([[1.0, 0.0], [0.0, 1.0], [0.7, 0.7]])  # action -> vector reward; each is optimal for some w


class Bandit(EnvBase):
    """One-step episodes, constant observation, three actions with the rewards ``R``."""

    def __init__(self, n):
        super().__init__(batch_size=[n])
        self.observation_spec = Composite(observation=Unbounded((n, 2)), shape=(n,))
        self.action_spec = Categorical(3, shape=(n,))
        self.reward_spec = Unbounded((n, 2))

    def _reset(self, td):
        n = self.batch_size[0]
        return TensorDict(observation=torch.ones(n, 2), done=torch.zeros(n, 1, dtype=torch.bool),
                          terminated=torch.zeros(n, 1, dtype=torch.bool), batch_size=[n])

    def _step(self, td):
        n = self.batch_size[0]
        return TensorDict(observation=torch.ones(n, 2), reward=R[td["action"]],
                          done=torch.ones(n, 1, dtype=torch.bool), terminated=torch.ones(n, 1, dtype=torch.bool),
                          batch_size=[n])

    def _set_seed(self, seed):
        return seed


def _bandit_agent(**overrides):
    cfg = resolve_config("morld_psa", "MOLavaGridDR-v0", pop_size=3, num_envs=4, frames_per_batch=12, hidden=(16,),
                         batch_size=32, lr=3e-3, target_update_period=10, update_frequency=1, init_random_frames=120,
                         exchange_every=10**9, seed=0, morld_schedule="concurrent", **overrides)
    env = TransformedEnv(Bandit(12), DiscountedVectorReturn(0.9))
    return cfg, env, make_morld_agent(cfg, env, gamma=0.9, device=CPU)


@pytest.mark.slow  # ~15-30 s on a shared CPU: ~350 population updates
def test_population_learns_a_front_no_single_member_covers():
    torch.manual_seed(0)
    cfg, env, agent = _bandit_agent()
    assert isinstance(agent, MORLDAgent)
    torch.testing.assert_close(agent.loss.weights, torch.tensor([[0.0, 1.0], [0.5012, 0.4988], [1.0, 0.0]]), atol=1e-4,
                               rtol=0)
    buffer = TensorDictReplayBuffer(storage=LazyTensorStorage(10_000))
    collector = Collector(env, agent.explore_policy, frames_per_batch=12, total_frames=1_200, init_random_frames=120,
                          exploration_type=ExplorationType.RANDOM, auto_register_policy_transforms=False)
    frames = 0
    for batch in collector:
        frames += batch.numel()
        morld.on_batch(agent, batch, buffer, frames)
    collector.shutdown()
    prefs = torch.tensor([[0.0, 1.0], [0.5, 0.5], [1.0, 0.0]])
    td = TensorDict(observation=torch.ones(3, 2), preference=prefs, batch_size=[3])
    with set_exploration_type(ExplorationType.DETERMINISTIC):
        actions = agent.eval_policy(td)["action"]
        members = agent.explore_policy(TensorDict(observation=torch.ones(12, 2), batch_size=[12]))["action"]
    # each member learned its own weight's best action; together they cover the three points of the front
    assert actions.tolist() == [1, 2, 0]
    assert members.view(3, 4).tolist() == [[1] * 4, [2] * 4, [0] * 4]
    front = {tuple(R[a].tolist()) for a in actions.tolist()}
    assert len(front) == 3  # a single member's (deterministic) policy gives one of these points


def test_exchange_archives_member_returns_and_adapts_weights():
    torch.manual_seed(0)
    # morld_eval_episodes=0: the archive takes the members' training episodes (the authors': separate
    # evaluation episodes, tests/recipes/test_mechanisms.py)
    cfg, env, agent = _bandit_agent(morld_eval_episodes=0)
    # three finished episodes: sub-envs 0 and 1 (member 0), 5 (member 1), 11 (member 2)
    done = torch.zeros(12, 1, 1, dtype=torch.bool)
    done[[0, 1, 5, 11]] = True
    ret = torch.zeros(12, 1, 2)
    ret[0], ret[1], ret[5], ret[11] = torch.tensor([0.0, 1.0]), torch.tensor([0.0, 3.0]), torch.tensor([0.7, 0.7]), \
        torch.tensor([0.1, 0.0])
    batch = TensorDict({"next": TensorDict(done=done, episode_discounted_return=ret, batch_size=[12, 1])}, [12, 1])
    agent.record_returns(batch)
    torch.testing.assert_close(agent.member_evaluations(),
                               torch.tensor([[0.0, 2.0], [0.7, 0.7], [0.1, 0.0]], dtype=torch.float64))
    before = agent.loss.weights.clone()
    agent.exchange()
    torch.testing.assert_close(agent.archive.evaluations,  # (0.1, 0) is dominated by (0.7, 0.7)
                               torch.tensor([[0.0, 2.0], [0.7, 0.7]], dtype=torch.float64))
    expected = psa_weights(before.double(), torch.tensor([[0.0, 2.0], [0.7, 0.7], [0.1, 0.0]], dtype=torch.float64),
                           agent.archive.evaluations, 0.1).float()
    torch.testing.assert_close(agent.loss.weights, expected)
    assert not torch.equal(agent.loss.weights, before)
    assert agent.member_evaluations().isnan().all()  # the next period starts afresh
    # the state (weights in the loss, archive, exchange bookkeeping) round-trips
    _, _, other = _bandit_agent(morld_eval_episodes=0)
    other.load_state_dict(agent.state_dict())
    torch.testing.assert_close(other.loss.weights, agent.loss.weights)
    assert other.archive.evaluations.tolist() == agent.archive.evaluations.tolist() and other.exchanges == 1


def test_sac_agent_learns_from_the_original_reward():
    from morl_trl.recipes.off_policy import make_training_env

    cfg = resolve_config("sac", "MOHopperDR-v5", quick=True, hidden=(16,), num_envs=2)
    pytest.importorskip("mujoco")
    env = make_training_env(cfg, CPU)
    agent = AGENT_BUILDERS["sac"](cfg, env, gamma=0.99, device=CPU)
    assert type(agent.loss).__name__ == "SACLoss" and agent.loss.tensor_keys.reward == "original_reward"
    td = env.rollout(4, agent.explore_policy, break_when_any_done=False).reshape(-1)
    buffer = TensorDictReplayBuffer(storage=LazyTensorStorage(100), batch_size=8)
    buffer.extend(td)
    from morl_trl.algorithms.actor_critic.recipe import update

    losses = update(agent, buffer)
    assert {"loss_actor", "loss_qvalue", "loss_alpha"} <= set(losses.keys())


# ---------------------------------------------------------------------- recipes and the CLI
ROOT = __import__("pathlib").Path(__file__).resolve().parents[2]


@pytest.mark.parametrize("algo, folder, domains", [
    ("morld", "morld", {"hopper": "MOHopperDR-v5", "half_cheetah": "MOHalfCheetahDR-v5", "humanoid": "MOHumanoidDR-v5",
                        "lunar_lander": "MOLunarLanderDR-v0", "lava_grid": "MOLavaGridDR-v0"}),
    ("sac", "sac", {"hopper": "MOHopperDR-v5", "half_cheetah": "MOHalfCheetahDR-v5", "humanoid": "MOHumanoidDR-v5",
                    "lunar_lander": "MOLunarLanderDR-v0", "lava_grid": "MOLavaGridDR-v0",
                    "mario": "MOSuperMarioBrosZeroShot-v2"}),
])
def test_paper_recipes_are_the_defaults_on_every_domain_the_paper_ran(algo, folder, domains):
    for name, env_id in domains.items():
        assert resolve_config(algo, "MOLavaGridDR-v0", config_file=ROOT / f"examples/{folder}/{name}_paper.toml") == \
            resolve_config(algo, env_id)


def test_quick_recipe_file_is_the_quick_preset():
    path = ROOT / "examples/morld/lava_grid_quick.toml"
    assert resolve_config("morld", "MOLavaGridDR-v0", config_file=path) == \
        resolve_config("morld", "MOLavaGridDR-v0", quick=True)


@pytest.mark.slow  # ~25 s: a whole run (build, 2 evaluations, report, checkpoints)
def test_cli_trains_and_evaluates_morld_psa(tmp_path):
    from morl_trl.cli import main

    run = tmp_path / "run"
    code = main(["train", "morld_psa", "MOLavaGridDR-v0", "--quick", "--frames", "600", "--run-dir", str(run),
                 "--no-progress", "init_random_frames=300", "exchange_every=300", "hidden=[16]", "eval_weights=2",
                 "eval_contexts=['MOLavaGridRoom-v0']", "eval_random_baseline=false", "batch_size=16"])
    assert code == 0
    rows = (run / "eval" / "metrics.csv").read_text().splitlines()
    assert len(rows) == 3  # header + frames 0 and 600, one context
    state = load_checkpoint(run / "checkpoints" / "frames_000000000600")
    assert state["agent"]["morld"]["exchanges"] == 2


def test_member_weights_are_the_energy_weights_of_the_run_seed_as_the_authors():
    # SPEC §6 MORL/D: population weights = equally_spaced_weights(d, pop, seed=run seed) (morld.py:143-144);
    # hyperparameters.toml morld.hopper.derived population_weights_script_seed (seed 5): the 0.5 grid
    from morl_trl.preferences import energy_weights

    record_hopper = [[0.0, 0.0, 1.0], [0.0, 0.5, 0.5], [0.0, 1.0, 0.0], [0.5, 0.0, 0.5], [0.5, 0.5, 0.0], [1.0, 0.0, 0.0]]
    torch.testing.assert_close(energy_weights(3, 6, seed=5), torch.tensor(record_hopper, dtype=torch.float64),
                               rtol=0, atol=1e-4)
    cfg, env, agent = _bandit_agent()  # 2 objectives, 3 members
    assert torch.equal(agent.loss.weights, energy_weights(2, 3, seed=cfg.seed, dtype=torch.float32))
    # SPEC §6: 2-D evenly spaced, extremes included (pymoo's energy directions: 0.5012 / 0.4988 inside)
    torch.testing.assert_close(agent.loss.weights, torch.tensor([[0.0, 1.0], [0.5, 0.5], [1.0, 0.0]]), rtol=0, atol=5e-3)


@pytest.mark.parametrize("fused_optimizer", [True, False])
def test_member_optimizers_follow_fused_optimizer(fused_optimizer):
    """The population's per-member Adams run torch's fused kernel unless fused_optimizer=false (as adam() for the
    other recipes), with the run's learning rates and Adam eps either way."""
    cfg = resolve_config("morld", "MOLavaGridDR-v0", pop_size=3, num_envs=1, hidden=(16,), seed=0,
                         morld_schedule="round_robin", fused_optimizer=fused_optimizer, adam_eps=1e-4)
    agent = make_morld_agent(cfg, TransformedEnv(Bandit(1), DiscountedVectorReturn(0.9)), gamma=0.9, device=CPU)
    opts = agent.optimizers
    assert {name: opt.fused for name, opt in opts.items()} == {name: fused_optimizer for name in opts}
    assert {opt.param_groups[0]["eps"] for opt in opts.values()} == {1e-4}


# ---------------------------------------------------------------------- the recipe's counters
# round robin: 3 members, turns of 20 frames (2 batches), 60 frames = 3 turns (one per member)
ROUND_ROBIN = dict(pop_size=3, num_envs=1, frames_per_batch=10, exchange_every=20, init_random_frames=10,
                   batch_size=8, hidden=(8,), frames=60, morld_update_passes=2, morld_eval_episodes=1,
                   eval_interval=40, eval_weights=2, checkpoint_interval=40, buffer_size=512, seed=0, progress=False,
                   eval_random_baseline=False)
LAVA = dict(target_update_period=5, eval_contexts=("MOLavaGridRoom-v0",))


def _trained(tmp_path, algo, env_id, **kw) -> dict:
    """The last checkpoint of a run of ``train_morld`` (the CLI's ``train``)."""
    train(resolve_config(algo, env_id, run_dir=str(tmp_path / "run"), **kw))
    return load_checkpoint(latest_checkpoint(tmp_path / "run"))


def _round_robin_counters(state, passes=2):
    m = state["agent"]["morld"]
    # 6 batches of 10 frames; the acting member updates once per frame after frame 10 (frames 11..59: 49);
    # at each of the 3 exchanges `passes` catch-up updates, each of the 2 other members at once
    assert (state["frames"], state["updates"]) == (60, 49 + 3 * passes)
    assert (m["exchanges"], m["env_resets"], m["active"], m["turn_frames"]) == (3, 3, 0, 0)
    assert m["frames_per_member"].tolist() == [20, 20, 20]
    # member 0: its turn's frames 11..19, then catch-ups at 2 exchanges; members 1 and 2: 20 + 2 catch-ups
    assert m["member_updates"].tolist() == [9 + 2 * passes, 20 + 2 * passes, 20 + 2 * passes]
    # one episode per member before training (the untrained members archived: morld_archive_initial) and at
    # each exchange
    assert m["eval_episodes"] == 3 + 3 * 3


def test_the_morld_recipe_counts_turns_updates_resets_and_exchanges_round_robin(tmp_path):
    _round_robin_counters(_trained(tmp_path, "morld", "MOLavaGridDR-v0", **ROUND_ROBIN, **LAVA))


@pytest.mark.slow  # (~10 s on a loaded 2-core machine: a run, evaluated)
def test_the_morld_psa_recipe_counts_as_morld_and_moves_the_weights(tmp_path):
    state = _trained(tmp_path, "morld_psa", "MOLavaGridDR-v0", **ROUND_ROBIN, **LAVA)
    _round_robin_counters(state)
    weights = state["agent"]["loss"]["weights"]  # (PSA moved them away from the energy weights)
    assert weights.shape == (3, 2) and not torch.equal(weights, energy_weights(2, 3, seed=0, dtype=torch.float32))


@pytest.mark.slow  # (~10 s on a loaded 2-core machine: a run, evaluated)
def test_the_morld_recipe_counts_updates_and_exchanges_concurrent(tmp_path):
    kw = dict(ROUND_ROBIN, frames_per_batch=12, num_envs=2, frames=60, updates_per_batch=2, exchange_every=24,
              eval_interval=36, checkpoint_interval=36)
    state = _trained(tmp_path, "morld", "MOLavaGridDR-v0", morld_schedule="concurrent", **kw, **LAVA)
    m = state["agent"]["morld"]
    # 5 batches of 12 frames (2 per member and sub-env), 2 updates of all members per batch (all past
    # init_random_frames=10); an exchange every 24 frames
    assert (state["frames"], state["updates"], m["exchanges"], m["env_resets"]) == (60, 10, 2, 0)


@pytest.mark.slow
@pytest.mark.skipif(importlib.util.find_spec("mujoco") is None, reason="needs mujoco")
def test_the_morld_recipe_counts_turns_updates_resets_and_exchanges_on_hopper(tmp_path):
    _round_robin_counters(_trained(tmp_path, "morld", "MOHopperDR-v5", **dict(ROUND_ROBIN, eval_weights=3),
                                   eval_contexts=("MOHopperDefault-v5",)))


def test_new_run_archives_the_untrained_members_before_frame_0(tmp_path, monkeypatch):
    """The authors' and MB's MORL/D ``train()`` evaluate and archive the untrained population before the loop
    (SPEC §6; MB 1.3.0 morld.py:537-543): once, with no weight adaptation and no exchange counted, before the
    frame-0 evaluation; a resumed run keeps its archive; ``morld_archive_initial=false`` starts empty."""
    from morl_trl.algorithms.morld.recipe import make_morld_training_env

    def lava_agent(**kw):
        cfg = resolve_config("morld_psa", "MOLavaGridDR-v0", quick=True, hidden=(8,), pop_size=3,
                             **{"morld_eval_episodes": 1, **kw})
        return make_morld_agent(cfg, make_morld_training_env(cfg, CPU), gamma=0.995, device=CPU)

    torch.manual_seed(0)
    agent = lava_agent()
    weights = agent.loss.weights.clone()
    members = agent.loss.actor_network_params.detach().clone()
    torch.manual_seed(1)
    expected = agent.evaluate_members()  # the archive evaluation the call runs, on the same draws
    agent.eval_episodes = 0
    torch.manual_seed(1)
    agent._eval_env = None  # (rebuilt with the same seed)
    assert agent.archive_initial_members()
    kept = [p for p in range(3) if not any(bool((expected[q] >= expected[p]).all() and (expected[q] > expected[p]).any())
                                           for q in range(3))]
    torch.testing.assert_close(agent.archive.evaluations, expected[kept])
    for person, p in zip(agent.archive.individuals, kept):  # the untrained member's weight and actor
        torch.testing.assert_close(person["weight"], weights[p])
        assert (person["actor"] == members.apply(lambda x: x[p])).all()
    assert agent.exchanges == 0 and agent.eval_episodes == 3 and torch.equal(agent.loss.weights, weights)
    assert not agent.archive_initial_members() and agent.eval_episodes == 3  # once: the archive is not empty
    for off in (dict(morld_archive_initial=False), dict(morld_eval_episodes=0)):
        other = lava_agent(**off)
        assert not other.archive_initial_members() and len(other.archive) == 0 and other.eval_episodes == 0
    # in the recipe: before the frame-0 evaluation, and not again on a resume
    calls = []
    real = MORLDAgent.archive_initial_members
    monkeypatch.setattr(MORLDAgent, "archive_initial_members",
                        lambda self: calls.append(len(self.archive)) or real(self))
    state = _trained(tmp_path, "morld", "MOLavaGridDR-v0", **{**ROUND_ROBIN, "frames": 20}, **LAVA)
    assert calls == [0] and state["agent"]["morld"]["eval_episodes"] == 3 + 3 and state["agent"]["morld"]["exchanges"] == 1
    from morl_trl.recipes.config.train_config import upgrade_keys
    assert upgrade_keys({}, "morld", "config.json", saved=True)["morld_archive_initial"] is False  # an older run
