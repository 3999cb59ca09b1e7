"""MO-Hopper, MO-HalfCheetah, MO-Humanoid: specs, contexts in the models, rewards, resets, peers."""

from __future__ import annotations

import numpy as np
import pytest
import torch
from tensordict import TensorDict
from torchrl.envs.utils import check_env_specs

pytest.importorskip("mujoco")

from morl_trl.envs import context_space, list_envs, make_env  # noqa: E402
from morl_trl.envs.mujoco import MOHalfCheetahEnv, MOHopperEnv, MOHumanoidEnv  # noqa: E402
from morl_trl.envs.mujoco.base import load_model  # noqa: E402

DOMAIN_IDS = [e for e in list_envs() if e.startswith(("MOHopper", "MOHalfCheetah", "MOHumanoid"))]



def actions(env, steps: int, seed: int = 0) -> torch.Tensor:
    """``[steps, num_envs, nu]`` uniform actions in the env's bounds."""
    spec = env.action_spec
    low, high = spec.space.low, spec.space.high
    u = torch.rand((steps, *spec.shape), generator=torch.Generator().manual_seed(seed))
    return low + (high - low) * u


def run(env, acts: torch.Tensor, auto_reset: bool = True):
    """Step ``acts`` through ``env``; return the stacked ``next`` TensorDicts and the step inputs."""
    td = env.reset()
    nexts, inputs = [], []
    for a in acts:
        td["action"] = a
        inputs.append(td.select("observation", "context", "action").clone())
        if auto_reset:
            out, td = env.step_and_maybe_reset(td)
            nexts.append(out["next"])
        else:
            td = env.step(td)["next"]
            nexts.append(td.clone())
    return torch.stack(nexts), torch.stack(inputs)


# ---------------------------------------------------------------- specs
def test_every_mujoco_id_is_registered():
    assert len(DOMAIN_IDS) == 3 + 6 + 5 + 5


@pytest.mark.parametrize("num_envs", [1, 8])
@pytest.mark.parametrize("env_id", DOMAIN_IDS)
def test_check_env_specs(env_id, num_envs):
    env = make_env(env_id, num_envs=num_envs, seed=0)
    check_env_specs(env, seed=0)


@pytest.mark.parametrize(
    "env_id, obs, k, low",
    [("MOHopperDefault-v5", 11, 3, -1.0), ("MOHalfCheetahDefault-v5", 17, 2, -1.0), ("MOHumanoidDefault-v5", 348, 2, -0.4)],
)
def test_shapes_and_action_bounds(env_id, obs, k, low):
    env = make_env(env_id, num_envs=3, seed=0)
    td = env.rollout(2)
    assert td["observation"].shape == (3, 2, obs)
    assert td["observation"].dtype == torch.float32
    assert td["next", "reward"].shape == (3, 2, k)
    assert td["next", "original_reward"].shape == (3, 2, 1)
    assert torch.equal(env.action_spec.space.low[0], torch.full_like(env.action_spec.space.low[0], low))
    assert len(env.objective_names) == k


# ---------------------------------------------------------------- contexts in the model
def test_default_ids_carry_the_xml_values_exactly():
    hopper = make_env("MOHopperDefault-v5", num_envs=2)
    xml = load_model("hopper.xml")
    for m in hopper.mj_models:
        assert np.array_equal(m.body_mass, xml.body_mass)  # 3.66519143..., not the rounded 3.6652
        assert np.array_equal(m.dof_damping, xml.dof_damping)
        assert np.array_equal(m.pair_friction[0, :2], [1.0, 1.0])
    np.testing.assert_allclose(xml.body_mass[1:5], [3.6652, 4.0579, 2.7814, 5.3156], atol=5e-5)
    cheetah = load_model("half_cheetah.xml")
    np.testing.assert_allclose(cheetah.body_mass[1:8], [6.2502, 1.5435, 1.5874, 1.0954, 1.4381, 1.2008, 0.8845], atol=5e-5)
    assert np.array_equal(cheetah.pair_friction[:, :2], np.full((2, 2), 0.4))
    humanoid = load_model("humanoid.xml")
    np.testing.assert_allclose(humanoid.body_mass[1:14], context_space("MOHumanoidDR-v5").default[:13], atol=5e-5)
    assert np.array_equal(humanoid.dof_damping[6:23], context_space("MOHumanoidDR-v5").default[13:])


def test_heavy_and_slippery_write_the_spec_arrays_only():
    xml = load_model("hopper.xml")
    heavy = make_env("MOHopperHeavy-v5", num_envs=2).mj_models[1]
    assert np.array_equal(heavy.body_mass[1:5], [9.0, 9.0, 8.5, 10.0])
    assert heavy.body_mass[1:5].sum() > xml.body_mass[1:5].sum()
    assert np.array_equal(heavy.body_inertia, xml.body_inertia)  # no inertia rescale
    assert np.array_equal(heavy.body_subtreemass, xml.body_subtreemass)  # no mj_setConst
    slippery = make_env("MOHopperSlippery-v5").mj_models[0]
    assert np.array_equal(slippery.pair_friction[0], [0.1, 0.1, 0.005, 0.0001, 0.0001])  # the decimal 0.1
    assert np.array_equal(slippery.body_mass[1:5], [3.7, 4.0, 2.8, 5.3])
    low_damping = make_env("MOHopperLowDamping-v5").mj_models[0]
    assert np.array_equal(low_damping.dof_damping, [0, 0, 0, 0.1, 0.1, 0.1])

    cheetah = make_env("MOHalfCheetahHard-v5").mj_models[0]
    # 6.2502 is the registered default: the model keeps the XML's exact torso mass
    xml_torso = load_model("half_cheetah.xml").body_mass[1]
    assert np.array_equal(cheetah.body_mass[1:8], [xml_torso, 9.5, 9.5, 9.5, 0.1, 0.1, 0.1])
    assert np.array_equal(cheetah.pair_friction[:, :2], np.full((2, 2), 0.1))

    humanoid = make_env("MOHumanoidHard-v5").mj_models[0]
    assert np.array_equal(humanoid.body_mass[10:14], [0.1, 0.1, 5.0, 5.0])
    assert np.array_equal(humanoid.dof_damping[6:23], [1.0] * 6 + [0.2] + [1.0] * 3 + [0.2] * 7)
    assert np.array_equal(humanoid.dof_damping[:6], np.zeros(6))


def test_context_changes_the_dynamics():
    default = make_env("MOHopperDefault-v5", num_envs=1, seed=5)
    heavy = make_env("MOHopperHeavy-v5", num_envs=1, seed=5)
    acts = actions(default, 10)
    a, _ = run(default, acts, auto_reset=False)
    b, _ = run(heavy, acts, auto_reset=False)
    # same seed, same initial state (the reset noise does not depend on the context) ...
    assert torch.equal(default.reset()["observation"], heavy.reset()["observation"])
    # ... but the heavier body moves differently under the same torques
    assert (a["observation"][-1] - b["observation"][-1]).abs().max() > 0.05


def test_friction_acts_only_through_the_foot_contact():
    acts = actions(make_env("MOHalfCheetahDefault-v5"), 40, seed=3)
    obs, first_contact = [], []
    for friction in (0.1, 2.0):
        env = make_env("MOHalfCheetahDefault-v5", num_envs=1, seed=1, friction=friction)
        td, trace, ncon = env.reset(), [], []
        for a in acts:
            td = env.step(td.set("action", a))["next"]
            trace.append(td["observation"][0])
            ncon.append(env.mj_data(0).ncon)
        obs.append(torch.stack(trace))
        first_contact.append(next(t for t, n in enumerate(ncon) if n))
    diff = (obs[0] - obs[1]).abs().amax(-1)
    first = min(first_contact)
    assert first >= 2 and diff[:first].max() == 0  # in the air friction plays no part
    assert diff[-1] > 0.01


# ---------------------------------------------------------------- rewards, by hand
def test_hopper_reward_by_hand_healthy_bonus_on_every_objective():
    env = make_env("MOHopperHard-v5", num_envs=1, seed=2)
    env.reset()
    acts = actions(env, 60, seed=1)
    saw_terminal = False
    for a in acts:
        before = env.mj_data(0).qpos.copy()
        out = env.step(TensorDict(action=a, batch_size=[1]))["next"]
        after = env.mj_data(0).qpos.copy()
        a64 = a[0].double().numpy()
        x_vel = (after[0] - before[0]) / 0.008
        sq = float(np.square(a64).sum())
        expected = np.array([x_vel, 10 * (after[1] - 1.25), -sq]) + 1.0
        np.testing.assert_allclose(out["reward"][0].numpy(), expected, rtol=1e-6, atol=1e-5)
        healthy = after[1] > 0.7 and abs(after[2]) < 0.2 and np.all(np.abs(np.r_[after[2:], env.mj_data(0).qvel]) < 100)
        assert bool(out["terminated"][0]) == (not healthy)
        np.testing.assert_allclose(out["original_reward"][0, 0].item(), x_vel + healthy - 1e-3 * sq, rtol=1e-6, atol=1e-5)
        if not healthy:  # the terminal step: +1 on every objective, no healthy term in the scalar
            saw_terminal = True
            assert out["reward"][0, 2].item() == pytest.approx(1.0 - sq, abs=1e-5)
            break
    assert saw_terminal


def test_cheetah_reward_by_hand():
    env = make_env("MOHalfCheetahLight-v5", num_envs=2, seed=0)
    env.reset()
    a = actions(env, 1)[0]
    before = env.mj_data(1).qpos.copy()
    out = env.step(TensorDict(action=a, batch_size=[2]))["next"]
    x_vel = (env.mj_data(1).qpos[0] - before[0]) / 0.05
    sq = float(np.square(a[1].double().numpy()).sum())
    np.testing.assert_allclose(out["reward"][1].numpy(), [x_vel, -sq], rtol=1e-6, atol=1e-5)
    assert out["original_reward"][1, 0].item() == pytest.approx(x_vel - 0.1 * sq, abs=1e-5)
    assert not out["terminated"].any()


def test_humanoid_reward_by_hand_uses_the_centre_of_mass_and_context_masses():
    env = make_env("MOHumanoidHeavy-v5", num_envs=1, seed=0)
    env.reset()
    mass = env.mj_models[0].body_mass
    assert mass[1] == 10.0

    def com_x():
        return float(mass @ env.mj_data(0).xipos[:, 0] / mass.sum())

    a = actions(env, 1)[0]
    before = com_x()
    out = env.step(TensorDict(action=a, batch_size=[1]))["next"]
    v = (com_x() - before) / 0.015
    sq = float(np.square(a[0].double().numpy()).sum())
    np.testing.assert_allclose(out["reward"][0].numpy(), [v + 2.0, -sq + 2.0], rtol=1e-6, atol=1e-5)
    assert out["original_reward"][0, 0].item() == pytest.approx(1.25 * v + 2.0 - 0.1 * sq, abs=1e-5)


# ---------------------------------------------------------------- domain randomization, seeding, resets
def test_dr_gives_a_context_per_subenv_and_per_episode():
    env = make_env("MOHopperDR-v5", num_envs=4, seed=0)
    space = context_space("MOHopperDR-v5")
    td = env.reset()
    first = td["context"].clone()
    assert space.contains(first)
    assert len({tuple(c.tolist()) for c in first}) == 4
    models = env.mj_models
    for i in range(4):  # the models carry the sampled contexts
        np.testing.assert_allclose(models[i].body_mass[1:5], first[i, :4].numpy(), rtol=1e-6)
        np.testing.assert_allclose(models[i].pair_friction[0, :2], first[i, 7].item(), rtol=1e-6)
    # a partial reset without a context entry draws for the reset sub-envs only
    env.reset(td.set("_reset", torch.tensor([[True], [False], [False], [True]])).select("_reset"))
    second = env.context  # (TorchRL zeroes the rows not reset in the returned TensorDict: they were not given)
    assert not torch.equal(second[0], first[0]) and not torch.equal(second[3], first[3])
    assert torch.equal(second[1:3], first[1:3])
    # one with the current contexts in the reset TensorDict keeps them (an explicit context)
    third = env.reset(td.set("context", second).set("_reset", torch.tensor([[True], [True], [False], [False]])))
    assert torch.equal(third["context"], second)


def test_same_seed_same_contexts_and_returns():
    def episode(seed):
        env = make_env("MOHalfCheetahDR-v5", num_envs=3, seed=seed)
        nexts, inputs = run(env, actions(env, 15, seed=7))
        return inputs["context"], nexts["reward"].sum(0)

    ctx_a, ret_a = episode(11)
    ctx_b, ret_b = episode(11)
    ctx_c, ret_c = episode(12)
    assert torch.equal(ctx_a, ctx_b) and torch.equal(ret_a, ret_b)
    assert not torch.equal(ctx_a, ctx_c) and not torch.equal(ret_a, ret_c)


def test_partial_reset_leaves_the_other_subenvs_on_their_trajectory():
    acts = actions(make_env("MOHalfCheetahDefault-v5", num_envs=2), 10, seed=4)
    ref = make_env("MOHalfCheetahDefault-v5", num_envs=2, seed=3)
    ref_next, _ = run(ref, acts, auto_reset=False)

    env = make_env("MOHalfCheetahDefault-v5", num_envs=2, seed=3)
    td = env.reset()
    for t in range(10):
        if t == 5:
            before = td["observation"].clone()
            td = env.reset(td.set("_reset", torch.tensor([[True], [False]])))
            assert torch.equal(td["observation"][1], before[1])
            assert (td["observation"][0] - before[0]).abs().max() > 0  # a fresh start
        td["action"] = acts[t]
        td = env.step(td)["next"]
    assert torch.equal(td["observation"][1], ref_next["observation"][-1, 1])
    assert not torch.equal(td["observation"][0], ref_next["observation"][-1, 0])


@pytest.mark.parametrize("env_id", ["MOHopperDefault-v5", "MOHumanoidDefault-v5"])
def test_partial_step_advances_only_the_selected_subenvs(env_id):
    ref = make_env(env_id, num_envs=2, seed=8)
    acts = actions(ref, 3, seed=1)
    ref_next, _ = run(ref, acts, auto_reset=False)

    env = make_env(env_id, num_envs=2, seed=8)
    td = env.reset()
    skipped_qpos = env.mj_data(1).qpos.copy()
    td = env.step(td.set("action", acts[0]).set("_step", torch.tensor([True, False])))["next"]
    assert np.array_equal(env.mj_data(1).qpos, skipped_qpos)  # sub-env 1 did not move
    assert torch.equal(td["observation"][0], ref_next["observation"][0, 0])
    for t in (1, 2):  # sub-env 0 continues on its own trajectory, full steps from now on
        td = env.step(td.set("action", acts[t]).exclude("_step"))["next"]
    assert torch.equal(td["observation"][0], ref_next["observation"][2, 0])
    assert torch.equal(td["reward"][0], ref_next["reward"][2, 0])


def test_truncation_after_max_episode_steps():
    env = make_env("MOHalfCheetahDefault-v5", num_envs=2, seed=0, max_episode_steps=4)
    td = env.rollout(4)
    assert td["next", "truncated"][:, -1].all() and not td["next", "truncated"][:, :-1].any()
    assert td["next", "done"][:, -1].all() and not td["next", "terminated"].any()


def test_results_do_not_depend_on_the_thread_count():
    one = MOHopperEnv(num_envs=4, seed=9, num_threads=1)
    two = MOHopperEnv(num_envs=4, seed=9, num_threads=2)
    acts = actions(one, 20)
    a, _ = run(one, acts)
    b, _ = run(two, acts)
    assert torch.equal(a["observation"], b["observation"]) and torch.equal(a["reward"], b["reward"])


# ---------------------------------------------------------------- bad input
@pytest.mark.parametrize(
    "cls, column, value, match",
    [
        (MOHopperEnv, 0, float("nan"), "mass_torso"),
        (MOHopperEnv, 3, 0.0, "mass_foot"),
        (MOHopperEnv, 7, -0.5, "friction"),
        (MOHopperEnv, 5, -0.1, "damping_leg"),
        (MOHalfCheetahEnv, 7, 0.0, "friction"),
        (MOHumanoidEnv, 20, -1.0, "damping_left_hip_x"),
    ],
)
def test_bad_context_raises_naming_the_parameter_and_changes_nothing(cls, column, value, match):
    env = cls(num_envs=2, seed=0)
    td = env.reset()
    before_ctx = env.context
    before_mass = env.mj_models[0].body_mass.copy()
    before_qpos = env.mj_data(0).qpos.copy()
    bad = before_ctx.clone()
    bad[0, column] = value
    with pytest.raises(ValueError, match=match):
        env.reset(td.set("context", bad))
    assert torch.equal(env.context, before_ctx)
    assert np.array_equal(env.mj_models[0].body_mass, before_mass)
    assert np.array_equal(env.mj_data(0).qpos, before_qpos)
    with pytest.raises(ValueError, match=match):
        cls(num_envs=2, context=bad)


def test_wrong_context_length_and_bad_actions_raise():
    with pytest.raises(ValueError, match=r"expected \[\.\.\., 8\]"):
        MOHopperEnv(context=torch.ones(7))
    env = MOHumanoidEnv(num_envs=2, seed=0)
    env.reset()
    with pytest.raises(ValueError, match="shape"):
        env.step(TensorDict(action=torch.zeros(2, 16), batch_size=[2]))
    with pytest.raises(ValueError, match="bounds"):
        env.step(TensorDict(action=torch.full((2, 17), 0.5), batch_size=[2]))  # Box is [-0.4, 0.4]
    with pytest.raises(ValueError, match="NaN"):
        env.step(TensorDict(action=torch.full((2, 17), float("nan")), batch_size=[2]))
    with pytest.raises(ValueError, match="num_threads"):
        MOHopperEnv(num_threads=0)


# ---------------------------------------------------------------- peers: Gymnasium v5 and MO-Gymnasium
def _gym_peer(name, **kwargs):
    pytest.importorskip("gymnasium.envs.mujoco.hopper_v5")  # Gymnasium's MuJoCo envs need imageio
    import gymnasium as gym

    return gym.make(name, **kwargs).unwrapped


@pytest.mark.parametrize(
    "env_id, overrides, peer_id, peer_kwargs, steps",
    [
        # our foot-floor pair at friction 2.0 is Gymnasium's dynamic foot contact
        ("MOHopperDefault-v5", {"friction": 2.0}, "Hopper-v5", {}, 60),
        ("MOHalfCheetahDefault-v5", {}, "HalfCheetah-v5", {}, 40),
        # the paper's f_SORL: healthy reward 2.0, no contact cost
        ("MOHumanoidDefault-v5", {}, "Humanoid-v5", {"healthy_reward": 2.0, "contact_cost_weight": 0.0}, 40),
    ],
)
def test_same_observations_and_scalar_reward_as_gymnasium(env_id, overrides, peer_id, peer_kwargs, steps):
    peer = _gym_peer(peer_id, **peer_kwargs)
    env = make_env(env_id, num_envs=2, seed=123, **overrides)
    acts = actions(env, steps, seed=5)
    nexts, inputs = run(env, acts)  # sub-env 0 resets when it terminates, as the peer below
    obs, _ = peer.reset(seed=123)
    resets = 0
    for t in range(steps):
        assert np.array_equal(inputs["observation"][t, 0].numpy(), obs.astype(np.float32)), t
        obs, r, terminated, _, _ = peer.step(acts[t, 0].numpy())
        assert np.array_equal(nexts["observation"][t, 0].numpy(), obs.astype(np.float32)), t
        assert nexts["original_reward"][t, 0, 0].item() == pytest.approx(r, rel=1e-6, abs=1e-5)
        assert bool(nexts["terminated"][t, 0]) == terminated
        if terminated:
            obs, _ = peer.reset()
            resets += 1
    if peer_id != "HalfCheetah-v5":
        assert resets >= 1  # the comparison went through an auto-reset


def test_hopper_vector_reward_vs_mo_gymnasium_differs_only_on_the_terminal_step():
    pytest.importorskip("gymnasium.envs.mujoco.hopper_v5")
    mo_gym = pytest.importorskip("mo_gymnasium")
    peer = mo_gym.make("mo-hopper-v5").unwrapped
    env = make_env("MOHopperDefault-v5", num_envs=1, seed=4, friction=2.0)
    acts = actions(env, 60, seed=2)
    nexts, _ = run(env, acts)
    peer.reset(seed=4)
    for t in range(60):
        _, vec, terminated, _, _ = peer.step(acts[t, 0].numpy())
        ours = nexts["reward"][t, 0].numpy()
        # MO-Gymnasium's healthy bonus is 0 on the terminal step; the paper's is always 1
        np.testing.assert_allclose(ours, vec + (1.0 if terminated else 0.0), rtol=1e-5, atol=1e-4)
        if terminated:
            break
    assert terminated
