"""MO-LunarLander as a batched TorchRL env: specs, context effects, DR, resets, peer parity.

Peer parity: our wind is always enabled, so MO-Gymnasium's env is made with
``enable_wind=True`` (it then draws the two wind indices from its generator, as ours does)
and ``wind_power=0, turbulence_power=0`` to switch the forces off. With that, observations,
reward vectors, the scalar reward and the done flags are the same floats at every step,
across episodes, also with wind on, with continuous actions, and against a peer that
simulates exhaust particles (``render_mode="rgb_array"``).
"""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest
import torch
from tensordict import TensorDict
from torchrl.envs.utils import check_env_specs, step_mdp

pytest.importorskip("Box2D")

from morl_trl.envs import make_env  # noqa: E402
from morl_trl.envs.lunar_lander import MOLunarLanderEnv  # noqa: E402
from morl_trl.envs.lunar_lander.random_streams import BlockUniformStreams  # noqa: E402
from morl_trl.envs.lunar_lander.spec import LUNAR_LANDER_CONTEXT  # noqa: E402

NOOP, LEFT, MAIN, RIGHT = range(4)
FPS = 50
VY_SCALE = (400 / 30 / 2) / FPS  # observation vy = velocity.y * VY_SCALE


def _ctx(**overrides) -> torch.Tensor:
    return LUNAR_LANDER_CONTEXT.make(overrides)


def _raw(name: str, value: float) -> torch.Tensor:
    """The default context with one entry set, unvalidated (for bad-input tests)."""
    ctx = LUNAR_LANDER_CONTEXT.default_tensor()
    ctx[LUNAR_LANDER_CONTEXT.index(name)] = value
    return ctx


def _run(env, actions):
    """Step a fresh reset of ``env`` through ``actions`` ([T, N] or [T, N, 2]); stacked next-tds."""
    td = env.reset()
    out = []
    for a in actions:
        td["action"] = torch.as_tensor(a)
        td = env.step(td)
        out.append(td["next"].clone())
        td = step_mdp(td)
    return torch.stack(out, 0)


# ---------------------------------------------------------------------------- specs
@pytest.mark.parametrize(
    "env_id",
    ["MOLunarLanderDR-v0", "MOLunarLanderHard-v0", "MOLunarLanderContinuousDR-v0", "MOLunarLanderContinuousWindy-v0"],
)
@pytest.mark.parametrize("num_envs", [1, 8])
def test_check_env_specs(env_id, num_envs):
    env = make_env(env_id, num_envs=num_envs, seed=0)
    check_env_specs(env, seed=0)
    td = env.rollout(4, break_when_any_done=False)
    assert td["next", "observation"].shape == (num_envs, 4, 8)
    assert td["next", "reward"].shape == (num_envs, 4, 4)
    assert td["next", "original_reward"].shape == (num_envs, 4, 1)
    assert td["context"].shape == (num_envs, 4, 7)


def test_spaces_and_names():
    disc = MOLunarLanderEnv(num_envs=3, seed=0)
    cont = MOLunarLanderEnv(num_envs=3, seed=0, continuous=True)
    assert disc.objective_names == ("landing", "shaping", "main_fuel", "side_fuel")
    assert disc.action_spec.space.n == 4 and disc.action_spec.shape == (3,)
    assert cont.action_spec.shape == (3, 2)
    assert cont.action_spec.space.low.min() == -1 and cont.action_spec.space.high.max() == 1
    assert make_env("MOLunarLanderContinuousHard-v0").continuous
    assert make_env("MOLunarLanderContinuousDR-v0").continuous
    assert not make_env("MOLunarLanderDR-v0").continuous
    assert make_env("MOLunarLanderDefault-v0", max_episode_steps=7).max_episode_steps == 7


# ---------------------------------------------------------------------------- the context acts
def test_gravity_changes_fall_speed_exactly():
    """Under noop and before any contact, vy differs by exactly dg * dt per Box2D step."""
    k = 20
    vy = {}
    for name in ("HighGravity", "Default", "LowGravity"):
        env = make_env(f"MOLunarLander{name}-v0", seed=4)
        td = _run(env, torch.zeros(k, 1, dtype=torch.long))
        assert not td["observation"][:, 0, 6:].any()  # still airborne
        vy[name] = td["observation"][-1, 0, 3].item()
    assert vy["HighGravity"] < vy["Default"] < vy["LowGravity"]
    steps = k + 1  # the reset performs one no-op step, as Gymnasium's does
    assert vy["HighGravity"] - vy["Default"] == pytest.approx(-3.0 * steps / FPS * VY_SCALE, abs=1e-4)
    assert vy["LowGravity"] - vy["Default"] == pytest.approx(7.0 * steps / FPS * VY_SCALE, abs=1e-4)


def test_engine_powers_scale_their_impulses():
    k = 10
    dvy, dw = {}, {}
    base = _run(MOLunarLanderEnv(context=_ctx(), seed=1), torch.zeros(k, 1, dtype=torch.long))
    for power in (10.0, 16.0):
        td = _run(MOLunarLanderEnv(context=_ctx(main_engine_power=power), seed=1), torch.full((k, 1), MAIN))
        dvy[power] = (td["observation"][-1, 0, 3] - base["observation"][-1, 0, 3]).item()
        assert td["reward"][:, 0, 2].tolist() == [-1.0] * k
    assert dvy[10.0] > 0.1
    assert dvy[16.0] / dvy[10.0] == pytest.approx(1.6, rel=0.02)
    for power in (0.3, 0.9):
        td = _run(MOLunarLanderEnv(context=_ctx(side_engine_power=power), seed=1), torch.full((k, 1), LEFT))
        dw[power] = (td["observation"][-1, 0, 5] - base["observation"][-1, 0, 5]).item()
        assert td["reward"][:, 0, 3].tolist() == [-1.0] * k
    assert abs(dw[0.3]) > 0.01
    assert dw[0.9] / dw[0.3] == pytest.approx(3.0, rel=0.02)


@pytest.mark.parametrize(
    "x_coeff,y_coeff,x_obs,y_obs",
    [(0.5, 1.0, 0.0, 1.41), (0.75, 1.0, 0.5, 1.41), (0.25, 0.7, -0.5, 0.81)],
)
def test_spawn_position(x_coeff, y_coeff, x_obs, y_obs):
    env = MOLunarLanderEnv(context=_ctx(initial_x_coeff=x_coeff, initial_y_coeff=y_coeff), seed=0)
    obs = env.reset()["observation"][0]
    # (x_obs, y_obs) = ((20 x - 10) / 10, (13.33 y - 3.93) / 6.67); the reset's no-op step
    # (with the random initial push) moves the lander by less than 0.02 in these units
    assert obs[0].item() == pytest.approx(x_obs, abs=0.02)
    assert obs[1].item() == pytest.approx(y_obs, abs=0.02)


@pytest.mark.parametrize("name", LUNAR_LANDER_CONTEXT.names)
def test_every_context_parameter_changes_the_trajectory(name):
    actions = torch.tensor([MAIN, LEFT, MAIN, RIGHT] * 8).reshape(-1, 1)
    lo, hi = (LUNAR_LANDER_CONTEXT.low[LUNAR_LANDER_CONTEXT.index(name)],
              LUNAR_LANDER_CONTEXT.high[LUNAR_LANDER_CONTEXT.index(name)])
    a = _run(MOLunarLanderEnv(context=_ctx(**{name: lo}), seed=2), actions)["observation"]
    b = _run(MOLunarLanderEnv(context=_ctx(**{name: hi}), seed=2), actions)["observation"]
    assert (a[-1] - b[-1]).abs().max() > 1e-3


def _shaping(obs: torch.Tensor) -> float:
    x, y, vx, vy, angle, _, leg1, leg2 = obs.double().tolist()
    return -100 * (x * x + y * y) ** 0.5 - 100 * (vx * vx + vy * vy) ** 0.5 - 100 * abs(angle) + 10 * (leg1 + leg2)


def test_landing_rewards_follow_spec():
    """A heuristic landing: +100 at rest with both legs down, fuel terms in {0, -1}, and the
    shaping objective telescopes to shaping(last) - shaping(first)."""
    pytest.importorskip("gymnasium")
    from gymnasium.envs.box2d.lunar_lander import heuristic

    pilot = SimpleNamespace(unwrapped=SimpleNamespace(continuous=False))  # what heuristic() reads
    env = MOLunarLanderEnv(context=_ctx(wind_power=0.0, turbulence_power=0.0), seed=1)
    td = env.reset()
    rewards, obs = [], [td["observation"][0]]
    for _ in range(1000):
        td["action"] = torch.tensor([heuristic(pilot, td["observation"][0].numpy())])
        td = env.step(td)
        rewards.append(td["next", "reward"][0])
        obs.append(td["next", "observation"][0])
        if td["next", "done"].item():
            break
        td = step_mdp(td)
    r = torch.stack(rewards)
    assert td["next", "terminated"].item() and not td["next", "truncated"].item()
    assert r[-1, 0].item() == 100.0 and (r[:-1, 0] == 0).all()
    assert obs[-1][6:].tolist() == [1.0, 1.0]
    assert r[:, 1].double().sum().item() == pytest.approx(_shaping(obs[-1]) - _shaping(obs[0]), abs=1e-2)
    assert len(r) == 203
    assert set(r[:, 2].tolist()) <= {0.0, -1.0} and set(r[:, 3].tolist()) <= {0.0, -1.0}


def test_continuous_engine_semantics():
    env = MOLunarLanderEnv(continuous=True, seed=0)
    actions = torch.tensor([[[-0.5, 0.3]], [[0.0, -0.5]], [[0.5, -0.8]], [[1.0, 0.9]], [[0.2, 0.6]]])
    r = _run(env, actions)["reward"][:, 0]
    # main: off for <= 0, else (a+1)/2; side: off for |a| <= 0.5, else |a|
    assert r[:, 2].tolist() == pytest.approx([0.0, 0.0, -0.75, -1.0, -0.6])
    assert r[:, 3].tolist() == pytest.approx([0.0, 0.0, -0.8, -0.9, -0.6])


# ---------------------------------------------------------------------------- DR, seeding
def test_domain_randomization_contexts_and_reproducibility():
    def rollout(seed):
        torch.manual_seed(seed)
        env = make_env("MOLunarLanderDR-v0", num_envs=4, seed=seed)
        return env.rollout(250, break_when_any_done=False)

    a = rollout(3)
    ctx0 = a["context"][:, 0]
    assert len({tuple(c.tolist()) for c in ctx0}) == 4  # one context per sub-env
    assert LUNAR_LANDER_CONTEXT.contains(a["context"])
    # the spawn follows each sub-env's own x coefficient
    assert a["observation"][:, 0, 0] == pytest.approx(2 * ctx0[:, 5] - 1, abs=0.01)
    # a new context after each episode end, constant within an episode
    done = a["next", "done"][..., 0]
    assert done.sum() >= 4
    for i, t in done.nonzero().tolist():
        if t + 1 < done.shape[1]:
            assert not torch.equal(a["context"][i, t + 1], a["context"][i, t])
    same = ~done[:, :-1]
    assert (a["context"][:, 1:][same] == a["context"][:, :-1][same]).all()
    b = rollout(3)
    assert torch.equal(a["context"], b["context"])
    assert torch.equal(a["next", "reward"], b["next", "reward"])
    assert torch.equal(a["next", "observation"], b["next", "observation"])
    c = rollout(4)
    assert not torch.equal(a["context"][:, 0], c["context"][:, 0])


def test_terminal_observations_survive_the_auto_reset():
    """The final observation of an episode stays in the rollout after its sub-env resets."""
    torch.manual_seed(0)
    td = make_env("MOLunarLanderDR-v0", num_envs=4, seed=3).rollout(200, break_when_any_done=False)
    ends = [(i, t) for i, t in td["next", "done"][..., 0].nonzero().tolist() if t + 1 < 200]
    assert len(ends) >= 4
    for i, t in ends:
        final, first = td["next", "observation"][i, t], td["observation"][i, t + 1]
        assert not torch.equal(final, first)
        assert first[1].item() > 0.7  # a new episode starts high up (y coefficient >= 0.7)
        if td["next", "reward"][i, t, 0].item() == -100.0:  # crashed on the ground or flew out
            assert final[0].abs().item() >= 1.0 or final[1].item() < 0.7


def test_subenvs_are_seeded_like_gymnasium_vector_envs():
    """Sub-env i of a batch behaves exactly like a single env seeded with seed + i."""
    actions = torch.randint(0, 4, (40, 3), generator=torch.Generator().manual_seed(0))
    batch = _run(MOLunarLanderEnv(num_envs=3, seed=10), actions)
    for i in range(3):
        single = _run(MOLunarLanderEnv(num_envs=1, seed=10 + i), actions[:, i : i + 1])
        assert torch.equal(batch["observation"][:, i], single["observation"][:, 0])
        assert torch.equal(batch["reward"][:, i], single["reward"][:, 0])


def test_block_streams_reproduce_a_plain_generator():
    rng = np.random.default_rng(0)
    streams = BlockUniformStreams(2, seed=7, block=5)
    ref = [np.random.default_rng(7), np.random.default_rng(8)]
    for _ in range(60):
        i = int(rng.integers(2))
        if rng.random() < 0.2:  # a reset: draws straight from the generator, integers included
            g = streams.generator(i)
            assert g.integers(-9999, 9999) == ref[i].integers(-9999, 9999)
            assert g.uniform() == ref[i].uniform()
        else:
            row = streams.take(np.array([i]))[0]
            assert row.tolist() == [ref[i].uniform(-1.0, 1.0), ref[i].uniform(-1.0, 1.0)]


# ---------------------------------------------------------------------------- resets, truncation
def test_partial_reset_touches_only_selected_subenvs():
    actions = torch.randint(0, 4, (30, 4), generator=torch.Generator().manual_seed(1))
    a, b = MOLunarLanderEnv(num_envs=4, seed=5), MOLunarLanderEnv(num_envs=4, seed=5)
    ta, tb = a.reset(), b.reset()
    for t in range(10):
        for env, td in ((a, ta), (b, tb)):
            td["action"] = actions[t]
        ta, tb = step_mdp(a.step(ta)), step_mdp(b.step(tb))
    new_ctx = a.context.clone()
    new_ctx[0] = _ctx(initial_x_coeff=0.3)
    # TorchRL's partial-reset contract: the input carries the data of the sub-envs not reset
    ta.set("_reset", torch.tensor([[True], [False], [True], [False]]))
    ta.set("context", new_ctx)
    reset_td = a.reset(ta.clone())
    assert torch.equal(reset_td["observation"][[1, 3]], tb["observation"][[1, 3]])
    assert not torch.equal(reset_td["observation"][[0, 2]], tb["observation"][[0, 2]])
    assert reset_td["observation"][0, 0].item() == pytest.approx(2 * 0.3 - 1, abs=0.01)
    assert torch.equal(a.context[1:], b.context[1:]) and a.context[0, 5].item() == pytest.approx(0.3)
    assert a._step_count.tolist() == [0, 10, 0, 10]
    ta = reset_td
    for t in range(10, 30):
        ta["action"], tb["action"] = actions[t], actions[t]
        ta, tb = a.step(ta), b.step(tb)
        assert torch.equal(ta["next", "observation"][[1, 3]], tb["next", "observation"][[1, 3]])
        ta, tb = step_mdp(ta), step_mdp(tb)


def test_truncation_at_max_episode_steps():
    env = make_env("MOLunarLanderDefault-v0", num_envs=2, seed=0, max_episode_steps=5)
    td = env.rollout(5, break_when_any_done=False, policy=lambda td: td.set("action", torch.zeros(2, dtype=torch.long)))
    assert td["next", "truncated"][..., 0].tolist() == [[False] * 4 + [True]] * 2
    assert not td["next", "terminated"].any()
    assert td["next", "done"][..., 0].tolist() == [[False] * 4 + [True]] * 2


# ---------------------------------------------------------------------------- bad input
@pytest.mark.parametrize(
    "bad,name",
    [
        (torch.zeros(6), "shape"),
        (_raw("gravity", float("nan")), "gravity"),
        (_raw("wind_power", float("inf")), "wind_power"),
        (_raw("main_engine_power", 0.0), "main_engine_power"),
        (_raw("side_engine_power", -0.1), "side_engine_power"),
    ],
)
def test_bad_context_raises_and_changes_nothing(bad, name):
    env = MOLunarLanderEnv(num_envs=2, seed=0)
    td = env.reset()
    before_ctx, before_worlds = env.context, list(env._worlds)
    with pytest.raises(ValueError, match=name):
        env.reset(TensorDict({"context": bad.expand(2, *bad.shape)}, batch_size=[2]))
    assert torch.equal(env.context, before_ctx) and env._worlds == before_worlds
    with pytest.raises(ValueError, match=name):
        MOLunarLanderEnv(num_envs=2, context=bad)
    td["action"] = torch.tensor([NOOP, NOOP])
    assert env.step(td)["next", "observation"].shape == (2, 8)  # still usable


@pytest.mark.parametrize(
    "continuous,action",
    [
        (False, torch.tensor([0, 4])),
        (False, torch.tensor([-1, 0])),
        (False, torch.tensor([[0, 1], [2, 3]])),
        (False, torch.tensor([0.5, 1.0])),
        (True, torch.tensor([[0.0, 1.5], [0.0, 0.0]])),
        (True, torch.tensor([[0.0, float("nan")], [0.0, 0.0]])),
        (True, torch.zeros(2, 3)),
    ],
)
def test_bad_action_raises(continuous, action):
    env = MOLunarLanderEnv(num_envs=2, seed=0, continuous=continuous)
    td = env.reset()
    td["action"] = action
    with pytest.raises(ValueError, match="action"):
        env.step(td)


def test_step_before_reset_raises():
    env = MOLunarLanderEnv(num_envs=2, seed=0)
    with pytest.raises(RuntimeError, match="reset"):
        env._step_subenvs(torch.zeros(2, dtype=torch.long))


# ---------------------------------------------------------------------------- rendering
def test_render_rgb_array_shows_the_lander_where_it_is():
    pytest.importorskip("PIL")
    contexts = torch.stack([_ctx(initial_x_coeff=x, initial_y_coeff=0.7) for x in (0.3, 0.7)])
    env = MOLunarLanderEnv(num_envs=2, context=contexts, seed=0)
    env.reset()
    frames = env.render(None)
    assert frames.shape == (2, 400, 600, 3) and frames.dtype == np.uint8
    for i, x_coeff in enumerate((0.3, 0.7)):
        lander = np.all(frames[i] == (128, 102, 230), axis=-1)
        rows, cols = lander.nonzero()
        assert lander.sum() > 300
        assert cols.mean() == pytest.approx(600 * x_coeff, abs=5)
        assert rows.mean() == pytest.approx(400 - 400 * 0.7, abs=15)  # image rows count from the top
    assert np.array_equal(env.render(1), frames[1])
    with pytest.raises(ValueError, match="mode"):
        env.render(mode="human")


def test_pixel_render_transform_records_every_subenv():
    pytest.importorskip("PIL")
    from torchrl.envs import TransformedEnv
    from torchrl.record import PixelRenderTransform

    env = TransformedEnv(MOLunarLanderEnv(num_envs=2, seed=0), PixelRenderTransform(index=None))
    assert env.rollout(2)["pixels"].shape == (2, 2, 400, 600, 3)


# ---------------------------------------------------------------------------- peer parity
def _peer_parity(seed, wind, turbulence, steps, *, continuous=False, render_mode=None, policy="random"):
    """Step MO-Gymnasium and our env side by side; assert identical floats at every step."""
    mo_gym = pytest.importorskip("mo_gymnasium")
    from gymnasium.envs.box2d.lunar_lander import heuristic

    # our wind is always enabled: the peer needs enable_wind=True so that it draws the two
    # wind indices from its generator too (wind_power=0 then switches the force off)
    peer = mo_gym.make(
        "mo-lunar-lander-continuous-v3" if continuous else "mo-lunar-lander-v3",
        enable_wind=True, wind_power=wind, turbulence_power=turbulence, render_mode=render_mode,
    )
    env = MOLunarLanderEnv(context=_ctx(wind_power=wind, turbulence_power=turbulence), seed=seed,
                           continuous=continuous)
    rng = np.random.default_rng(seed)
    obs, _ = peer.reset(seed=seed)
    td = env.reset()
    assert np.array_equal(td["observation"][0].numpy(), obs)
    episodes = landings = 0
    for _ in range(steps):
        if policy == "heuristic":
            a = heuristic(peer, obs)
        else:
            a = rng.uniform(-1, 1, 2).astype(np.float32) if continuous else int(rng.integers(4))
        obs, r, term, trunc, info = peer.step(a)
        if render_mode is not None:
            peer.render()  # ages and removes the exhaust particles as Gymnasium does
        td["action"] = torch.as_tensor(np.asarray(a, dtype=np.float32))[None] if continuous else torch.tensor([a])
        td = env.step(td)
        nxt = td["next"]
        assert np.array_equal(nxt["observation"][0].numpy(), obs)
        assert np.array_equal(nxt["reward"][0].numpy(), r)
        assert nxt["original_reward"][0, 0].item() == np.float32(info["original_reward"])
        assert nxt["terminated"].item() == term and nxt["truncated"].item() == trunc
        if term or trunc:
            episodes += 1
            landings += r[0] == 100
            obs, _ = peer.reset()
            td = env.reset()
            assert np.array_equal(td["observation"][0].numpy(), obs)
        else:
            td = step_mdp(td)
    return episodes, landings


_PEER_WARNINGS = pytest.mark.filterwarnings("ignore:.*precision lowered:UserWarning")


@_PEER_WARNINGS
@pytest.mark.parametrize("seed", [0, 1])
def test_same_floats_as_mo_gymnasium_without_wind(seed):
    episodes, _ = _peer_parity(seed, 0.0, 0.0, steps=800)
    assert episodes >= 5  # several resets: the generators stay in step across episodes


@_PEER_WARNINGS
def test_same_floats_as_mo_gymnasium_heuristic_landings():
    episodes, landings = _peer_parity(0, 0.0, 0.0, steps=900, policy="heuristic")
    assert landings >= 2


@_PEER_WARNINGS
def test_same_floats_as_mo_gymnasium_with_wind_and_continuous():
    _peer_parity(5, 15.0, 1.5, steps=300)
    _peer_parity(7, 15.0, 1.5, steps=300, continuous=True)


@_PEER_WARNINGS
def test_skipping_exhaust_particles_keeps_the_trajectory():
    """The peer in rgb_array mode simulates exhaust particles; the lander moves identically."""
    pytest.importorskip("pygame")
    _peer_parity(2, 0.0, 0.0, steps=200, render_mode="rgb_array", policy="heuristic")


def test_partial_steps_skip_the_unselected_worlds():
    """A "_step" mask advances only the selected landers; the others keep their exact state."""
    full = make_env("MOLunarLanderDefault-v0", num_envs=3, seed=5)
    part = make_env("MOLunarLanderDefault-v0", num_envs=3, seed=5)
    a, b = full.reset(), part.reset()
    actions = torch.tensor([2, 1, 3])
    a["action"] = actions
    b["action"] = actions
    b["_step"] = torch.tensor([True, False, True])
    out_full, out_part = full.step(a)["next"], part.step(b)["next"]
    assert torch.equal(out_part["observation"][[0, 2]], out_full["observation"][[0, 2]])
    assert torch.equal(out_part["reward"][[0, 2]], out_full["reward"][[0, 2]])
    assert torch.equal(out_part["observation"][1], b["observation"][1])  # the skipped lander did not move
    assert out_part["reward"][1].abs().sum() == 0


@_PEER_WARNINGS
def test_batched_auto_reset_matches_one_peer_per_subenv():
    """``step_and_maybe_reset`` on 4 sub-envs (partial resets of whichever finished) gives the
    same floats as 4 MO-Gymnasium envs seeded ``seed + i``, each reset when it ends."""
    mo_gym = pytest.importorskip("mo_gymnasium")
    n, seed = 4, 3
    peers = [mo_gym.make("mo-lunar-lander-v3", enable_wind=True) for _ in range(n)]
    obs = np.stack([p.reset(seed=seed + i)[0] for i, p in enumerate(peers)])
    env = make_env("MOLunarLanderDefault-v0", num_envs=n, seed=seed)
    td = env.reset()
    assert np.array_equal(td["observation"].numpy(), obs)
    actions = np.random.default_rng(seed).integers(0, 4, size=(400, n))
    resets = 0
    for a in actions:
        td["action"] = torch.as_tensor(a)
        out, td = env.step_and_maybe_reset(td)
        for i, p in enumerate(peers):
            o, r, term, trunc, info = p.step(int(a[i]))
            assert np.array_equal(out["next", "observation"][i].numpy(), o)
            assert np.array_equal(out["next", "reward"][i].numpy(), r)
            assert out["next", "original_reward"][i, 0].item() == np.float32(info["original_reward"])
            assert out["next", "terminated"][i].item() == term
            if term or trunc:
                o, _ = p.reset()
                resets += 1
            assert np.array_equal(td["observation"][i].numpy(), o)
    assert resets >= 8


def test_wind_table_is_gymnasiums_formula_and_grows_past_its_end():
    import math

    from morl_trl.envs.lunar_lander import env as lander_env

    table = lander_env._WIND_TABLE
    for k in (-9999, -1234, 0, 1, 777, 9998):
        expected = math.tanh(math.sin(0.02 * k) + math.sin(math.pi * 0.01 * k))  # Gymnasium's expression
        assert table.values[k + table.OFFSET] == expected
    env = MOLunarLanderEnv(num_envs=2, seed=0)
    env.reset()
    end = len(table.values)
    env._wind_idx[:] = end - 1  # as after a very long airborne episode
    env._wind_guard[0] = 0
    td = env.step(TensorDict(action=torch.zeros(2, dtype=torch.long), batch_size=[2]))
    assert len(table.values) > end + 1000 and torch.isfinite(td["next", "observation"]).all()
    k = end - table.OFFSET
    assert table.values[end] == math.tanh(math.sin(0.02 * k) + math.sin(math.pi * 0.01 * k))
    assert env._wind_idx.tolist() == [[end, end]] * 2  # both airborne: one step further
