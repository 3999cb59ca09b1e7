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
        np.testing.assert_allclose(out["original_reward"][0, 0].item(), x_vel + 1.0 - 1e-3 * sq, rtol=1e-6, atol=1e-5)
        if not healthy:  # the terminal step: +1 on every objective and in the scalar (the authors')
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
    assert out["original_reward"][0, 0].item() == pytest.approx(1.25 * v + 2.0 - 1e-3 * sq, abs=1e-5)


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
def _asset(name: str) -> str:
    from importlib import resources

    return str(resources.files("morl_trl.envs.mujoco").joinpath("assets", name))


def _gym_peer(name, **kwargs):
    pytest.importorskip("gymnasium.envs.mujoco.hopper_v5")  # Gymnasium's MuJoCo envs need imageio
    import gymnasium as gym

    return gym.make(name, **kwargs).unwrapped


@pytest.mark.parametrize(
    "env_id, overrides, peer_id, peer_kwargs, steps",
    [
        # Gymnasium's Hopper-v5 code on our (the authors') model: a foot-floor pair at MuJoCo's defaults
        ("MOHopperDefault-v5", {}, "Hopper-v5", {"xml_file": _asset("hopper.xml")}, 60),
        ("MOHalfCheetahDefault-v5", {}, "HalfCheetah-v5", {}, 40),
        # the paper's f_SORL: healthy reward 2.0, no contact cost, control cost 0.001
        ("MOHumanoidDefault-v5", {}, "Humanoid-v5",
         {"healthy_reward": 2.0, "contact_cost_weight": 0.0, "ctrl_cost_weight": 1e-3}, 40),
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
        if terminated:  # Gymnasium v5 pays no healthy term on the terminal step; the authors do
            r += {"Hopper-v5": 1.0, "Humanoid-v5": 2.0}[peer_id]
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
    peer = mo_gym.make("mo-hopper-v5", xml_file=_asset("hopper.xml")).unwrapped
    env = make_env("MOHopperDefault-v5", num_envs=1, seed=4)
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


# ---------------------------------------------------------------- the authors' Hopper model, step for step
# Observations at steps 0, 100, 200, 300 of a 300-step rollout (seed 7, actions
# ``default_rng(0).uniform(-1, 1, (300, 3))`` as float32), computed once by ``_plain_mujoco_hopper``
# below (plain MjModel/MjData on the XML, the context written as SPEC 1.2 says) with the
# foot-floor <pair> at MuJoCo's defaults (solimp 0.9 0.95 0.001, margin 0), as the authors' is.
# With our former pair (solimp .8 .8 .01, margin 0.002) the trajectories part after 5-10 steps.
_HOPPER_FINGERPRINT_STEPS = (0, 100, 200, 300)
_HOPPER_FINGERPRINT = {
    "Default": [
        [1.25397217, 0.00275685685, -0.00274792803, -0.00199833722, 0.00373553438, -0.0049473471, 0.0032122843, 0.00297069433, -0.000320650463, -0.00196967577, -0.00221574376],
        [1.1850419, -0.13934359, -0.0212409385, -0.409319341, 0.283381492, 0.978488028, -0.0226023495, 3.55328202, 3.19578028, 0.0169200636, 0.238972664],
        [0.621321023, 1.01538932, -0.153535768, -0.166248307, 0.664282501, 1.89216268, -2.05663991, 2.47366643, -0.400095791, 1.12818086, -0.717206776],
        [0.38035354, 0.858837605, -0.322336227, -0.805129588, -0.111565761, 0.667191207, -0.774425685, 4.28627872, 2.36716914, 2.56615543, 0.732421637],
    ],
    "Light": [
        [1.25397217, 0.00275685685, -0.00274792803, -0.00199833722, 0.00373553438, -0.0049473471, 0.0032122843, 0.00297069433, -0.000320650463, -0.00196967577, -0.00221574376],
        [1.28606355, -0.26162082, 0.0183764677, -0.0422382951, 0.806405902, -0.720372856, 0.0802661553, -0.0229112674, 1.08561039, -1.38980985, 0.413317531],
        [0.286632806, -1.7417599, -0.0617419742, -0.580311835, -0.379995644, -0.439310312, -3.91368961, -5.3219285, -1.73488939, -1.15268219, -3.33374906],
        [0.0957334712, -4.92684937, -2.13933849, -1.85050321, 0.0513072759, -1.19847465, 0.0800122917, -0.767910063, -0.987380803, 2.8566947, 3.24686027],
    ],
    "Slippery": [
        [1.25397217, 0.00275685685, -0.00274792803, -0.00199833722, 0.00373553438, -0.0049473471, 0.0032122843, 0.00297069433, -0.000320650463, -0.00196967577, -0.00221574376],
        [1.16600037, -0.0372321308, -0.0206224248, -0.464574754, 0.46266064, 1.14475369, -0.13511084, 3.95676589, 3.19329405, -0.0459959693, 1.20558918],
        [0.0307116415, 1.57706571, -0.159406036, -0.307100177, 0.432815135, 0.0279099122, 0.38115862, -0.303432196, -0.0472957306, -0.383100837, -3.11487293],
        [0.426333517, 0.0843091384, -1.12540209, -0.883312225, 0.430785239, 0.423929602, -0.424019068, 2.77354765, 0.785641313, 2.59342599, 2.48074818],
    ],
}
_HOPPER_CONTEXTS = {  # SPEC 1.2: body_mass[1:5], dof_damping[3:6], pair_friction[0, :2]
    "Default": None,  # the XML's own values (the authors' Default env never calls set_task)
    "Light": ([0.5, 0.5, 0.3, 0.7], 1.0, 1.0),
    "Slippery": ([3.7, 4.0, 2.8, 5.3], 1.0, 0.1),
}


def _plain_mujoco_hopper(name: str, seed: int, acts: np.ndarray, *, pair_solimp=None, pair_margin=None) -> np.ndarray:
    """``[len(acts) + 1, 11]`` Hopper observations from plain ``mujoco`` (no morl_trl code)."""
    import mujoco
    from importlib import resources

    model = mujoco.MjModel.from_xml_path(str(resources.files("morl_trl.envs.mujoco").joinpath("assets", "hopper.xml")))
    if _HOPPER_CONTEXTS[name] is not None:
        masses, damping, friction = _HOPPER_CONTEXTS[name]
        model.body_mass[1:5] = masses
        model.dof_damping[3:6] = damping
        model.pair_friction[0, :2] = friction
    if pair_solimp is not None:
        model.pair_solimp[0, :3] = pair_solimp
        model.pair_margin[0] = pair_margin
    data = mujoco.MjData(model)
    rng = np.random.default_rng(seed)  # Gymnasium v5's reset noise, U(+-5e-3)
    data.qpos[:] = model.qpos0 + rng.uniform(-5e-3, 5e-3, model.nq)
    data.qvel[:] = rng.uniform(-5e-3, 5e-3, model.nv)
    mujoco.mj_forward(model, data)

    def observe():
        return np.r_[data.qpos[1:], np.clip(data.qvel, -10.0, 10.0)]

    obs = [observe()]
    for a in acts:
        data.ctrl[:] = a
        mujoco.mj_step(model, data, nstep=4)  # frame_skip 4
        obs.append(observe())
    return np.array(obs)


@pytest.mark.parametrize("name", sorted(_HOPPER_CONTEXTS))
def test_hopper_foot_contact_pair_takes_mujoco_defaults_as_the_authors_model(name):
    model = load_model("hopper.xml")
    np.testing.assert_array_equal(model.pair_solimp[0], [0.9, 0.95, 0.001, 0.5, 2.0])
    assert model.pair_margin[0] == 0.0 and model.pair_gap[0] == 0.0
    np.testing.assert_array_equal(model.pair_solref[0], [0.02, 1.0])
    assert model.pair_dim[0] == 3

    acts = np.random.default_rng(0).uniform(-1, 1, (300, 3)).astype(np.float32)
    env = make_env(f"MOHopper{name}-v5", num_envs=1, seed=7)
    td = env.reset()
    ours = [td["observation"][0].numpy()]
    for a in acts:  # 300 steps, straight through the termination (the physics goes on)
        td = env.step(td.set("action", torch.from_numpy(a)[None]))["next"]
        ours.append(td["observation"][0].numpy())
    ours = np.array(ours, dtype=np.float64)
    reference = _plain_mujoco_hopper(name, 7, acts.astype(np.float64))
    np.testing.assert_allclose(ours, reference, rtol=0, atol=1e-6)  # float32 observations
    np.testing.assert_array_equal(ours, reference.astype(np.float32))  # in fact bit for bit
    np.testing.assert_allclose(reference[list(_HOPPER_FINGERPRINT_STEPS)], _HOPPER_FINGERPRINT[name], rtol=1e-6, atol=1e-7)
    np.testing.assert_allclose(ours[list(_HOPPER_FINGERPRINT_STEPS)], _HOPPER_FINGERPRINT[name], rtol=1e-6, atol=1e-7)
    # the former pair (the geoms' solimp .8 .8 .01, margin 0.002) leaves that trajectory
    former = _plain_mujoco_hopper(name, 7, acts.astype(np.float64), pair_solimp=[0.8, 0.8, 0.01], pair_margin=0.002)
    assert np.abs(former[300] - reference[300]).max() > 0.1


# ---------------------------------------------------------------- the authors' scalar rewards, by hand
def test_hopper_original_reward_keeps_healthy_term_on_terminal_step_as_the_authors():
    env = make_env("MOHopperDefault-v5", num_envs=1, seed=3)
    env.reset()
    a = torch.tensor([[0.5, -0.5, 1.0]])  # sum of squares 1.5
    seen = {"normal": False, "terminal": False}
    for _ in range(200):
        x0 = env.mj_data(0).qpos[0]
        out = env.step(TensorDict(action=a, batch_size=[1]))["next"]
        v = (env.mj_data(0).qpos[0] - x0) / 0.008
        # x_velocity + healthy 1.0 - 0.001 * 1.5, the healthy term kept on every step
        assert out["original_reward"][0, 0].item() == pytest.approx(v + 1.0 - 0.0015, abs=1e-5)
        kind = "terminal" if out["terminated"][0] else "normal"
        seen[kind] = True
        if kind == "terminal":
            break
    assert seen == {"normal": True, "terminal": True}


def test_humanoid_original_reward_uses_ctrl_cost_0_001_and_keeps_healthy_term_as_the_authors():
    env = make_env("MOHumanoidDefault-v5", num_envs=1, seed=0)
    env.reset()
    mass = env.mj_models[0].body_mass
    a = torch.full((1, 17), 0.4)  # sum of squares 17 * 0.16 = 2.72: control cost 0.00272 (Gymnasium's 0.1 gives 0.272)
    seen = {"normal": False, "terminal": False}
    for _ in range(200):
        x0 = float(mass @ env.mj_data(0).xipos[:, 0] / mass.sum())
        out = env.step(TensorDict(action=a, batch_size=[1]))["next"]
        v = (float(mass @ env.mj_data(0).xipos[:, 0] / mass.sum()) - x0) / 0.015
        assert out["original_reward"][0, 0].item() == pytest.approx(1.25 * v + 2.0 - 0.00272, abs=1e-5)
        kind = "terminal" if out["terminated"][0] else "normal"
        seen[kind] = True
        if kind == "terminal":  # z left (1, 2): Gymnasium v5 would pay 1.25 v - 0.272 here
            assert env.mj_data(0).qpos[2] <= 1.0 or env.mj_data(0).qpos[2] >= 2.0
            break
    assert seen == {"normal": True, "terminal": True}


def test_negative_damping_is_rejected_with_its_name_and_row():
    # allow_extrapolation lets a context past the declared bounds; MuJoCo must still not get
    # a negative damping (the shared MujocoContextEnv check over its nonnegative columns)
    with pytest.raises(ValueError, match=r"'damping_leg' is -0\.5 \(row 0\); it must be >= 0"):
        make_env("MOHopperDefault-v5", damping_leg=-0.5, allow_extrapolation=True)
    env = make_env("MOHopperDefault-v5", damping_leg=0.0, allow_extrapolation=True)  # 0: an undamped joint
    assert env.mj_models[0].dof_damping[4] == 0.0
