"""The DeepMind Control Suite domains: the same physics, observations and rewards as
``dm_control.suite.load`` at the default context, contexts written into the sub-envs' models,
the suite's terms as objectives, snapshots."""

from __future__ import annotations

import numpy as np
import pytest
import torch
from tensordict import TensorDict

pytest.importorskip("dm_control", reason="the DMC domains need dm_control (pip install 'morl-trl[dmc]')")

from dm_control import suite  # noqa: E402

from morl_trl.envs import context_space, domain_of, evaluation_suite, make_env  # noqa: E402

# our fixed-context prefix -> (suite domain, task, control timestep or None: one physics step)
SUITE_TASKS = {
    "DMCWalker": ("walker", "walk", 0.025),
    "DMCWalkerRun": ("walker", "run", 0.025),
    "DMCCheetah": ("cheetah", "run", None),
    "DMCHopper": ("hopper", "hop", 0.02),
}


def _flat(observation) -> np.ndarray:
    return np.concatenate([np.asarray(v, dtype=np.float64).ravel() for v in observation.values()])


def _peer(prefix: str, seed: int, steps: int):
    domain, task, control = SUITE_TASKS[prefix]
    limit = (steps - 0.5) * (control or suite.load(domain, task).physics.timestep())  # (no float edge)
    return suite.load(domain, task, task_kwargs={"random": seed, "time_limit": limit})


@pytest.mark.parametrize("prefix", list(SUITE_TASKS))
def test_default_context_equals_dm_control_suite_across_an_auto_reset(prefix):
    """Observations and ``original_reward`` equal the suite's bit for bit (in float32), for the
    same actions and the same initial states (sub-env i: ``task_kwargs={"random": seed + i}``),
    through two 6-step episodes (our auto-reset and the peer's ``reset`` draw from the same
    generator)."""
    n, seed, horizon = 2, 7, 6
    env = make_env(f"{prefix}Default-v0", num_envs=n, seed=seed, max_episode_steps=horizon)
    peers = [_peer(prefix, seed + i, horizon) for i in range(n)]
    td = env.reset()
    first = np.stack([_flat(p.reset().observation) for p in peers]).astype(np.float32)
    np.testing.assert_array_equal(td["observation"].numpy(), first)
    actions = np.random.default_rng(0).uniform(-1, 1, size=(2 * horizon, n, env.action_spec.shape[-1]))
    for t, a in enumerate(actions.astype(np.float32)):
        td["action"] = torch.from_numpy(a)
        td, nxt_root = env.step_and_maybe_reset(td)
        steps = [p.step(a[i].astype(np.float64)) for i, p in enumerate(peers)]
        obs = np.stack([_flat(s.observation) for s in steps]).astype(np.float32)
        rew = np.array([s.reward for s in steps], dtype=np.float32)
        np.testing.assert_array_equal(td["next", "observation"].numpy(), obs, err_msg=f"step {t}")
        np.testing.assert_array_equal(td["next", "original_reward"].numpy()[:, 0], rew, err_msg=f"step {t}")
        done = bool(steps[0].last())
        assert td["next", "truncated"].all().item() is done and not td["next", "terminated"].any()
        if done:  # the peer's next episode: the same generator continues
            first = np.stack([_flat(p.reset().observation) for p in peers]).astype(np.float32)
            np.testing.assert_array_equal(nxt_root["observation"].numpy(), first)
        td = nxt_root


@pytest.mark.parametrize("prefix", list(SUITE_TASKS))
def test_objectives_are_the_suite_terms_in_unit_range(prefix):
    env = make_env(f"{prefix}Default-v0", num_envs=4, seed=0)
    td = env.rollout(40)
    r, original = td["next", "reward"].double(), td["next", "original_reward"][..., 0].double()
    assert r.min() >= 0 and r.max() <= 1
    energy = 1 - (td["action"].double() ** 2).mean(-1)  # the suite's small_control for |a| <= 1
    torch.testing.assert_close(r[..., -1], energy, rtol=0, atol=1e-6)
    if prefix.startswith("DMCWalker"):  # stand * (5 * speed + 1) / 6
        recombined = r[..., 1] * (5 * r[..., 0] + 1) / 6
    elif prefix == "DMCHopper":  # stand * hop
        recombined = r[..., 0] * r[..., 1]
    else:  # the suite's reward is the speed term
        recombined = r[..., 0]
    torch.testing.assert_close(recombined, original, rtol=0, atol=1e-6)


def test_walker_run_needs_eight_times_the_speed_of_walk():
    """The same states (seed, actions): a walker at 1.2 m/s scores speed 1 in walk and
    tolerance(1.2, (8, inf), margin 4, value_at_margin .5, linear) = 1 - .5 * 6.8 / 4 = 0.15 in run."""
    from morl_trl.envs.dmc.base import tolerance

    assert tolerance(np.array([1.2]), bounds=(1.0, np.inf), margin=0.5, value_at_margin=0.5, sigmoid="linear")[0] == 1
    assert tolerance(np.array([1.2]), bounds=(8.0, np.inf), margin=4.0, value_at_margin=0.5,
                     sigmoid="linear")[0] == pytest.approx(0.15)
    walk, run = (make_env(f"DMCWalker{t}Default-v0", num_envs=2, seed=1) for t in ("", "Run"))
    torch.manual_seed(0)
    a, b = walk.rollout(20, break_when_any_done=False), None
    torch.manual_seed(0)
    b = run.rollout(20, break_when_any_done=False)
    torch.testing.assert_close(a["next", "observation"], b["next", "observation"], rtol=0, atol=0)
    torch.testing.assert_close(a["next", "reward"][..., 1:], b["next", "reward"][..., 1:], rtol=0, atol=0)


def test_contexts_are_written_into_each_sub_envs_model():
    space = context_space("DMCWalkerDR-v0")
    ctx = torch.stack([space.default_tensor(),
                       space.make(gravity=-4.905, friction=0.2, actuator_strength=0.5, joint_damping=2.0,
                                  joint_stiffness=3.0, mass=2.0, torso_mass=1.5, timestep=0.002)])
    env = make_env("DMCWalkerDefault-v0", num_envs=2, seed=0)
    env.reset(TensorDict(context=ctx, batch_size=[2]))
    base, m = env.mj_models
    torso = base.body("torso").id
    assert base.opt.gravity[2] == -9.81 and m.opt.gravity[2] == -4.905
    assert base.geom_friction[0, 0] == 0.7 and m.geom_friction[0, 0] == pytest.approx(0.14)  # the floor
    assert base.actuator_gear[:, 0].tolist() == [100, 50, 20, 100, 50, 20]
    assert m.actuator_gear[:, 0].tolist() == [50, 25, 10, 50, 25, 10]
    assert m.dof_damping.tolist() == [0, 0, 0] + [0.2] * 6  # XML .1, roots 0
    assert base.jnt_stiffness.tolist() == [0] * 9 and m.jnt_stiffness.tolist() == [0] * 3 + [3.0] * 6
    np.testing.assert_allclose(m.body_mass[1:], base.body_mass[1:] * np.where(np.arange(1, 8) == torso, 3.0, 2.0))
    np.testing.assert_allclose(m.body_inertia[torso], base.body_inertia[torso] * 3.0)
    # mj_setConst: the subtree mass (which the suite's speed sensor uses) follows
    assert m.body_subtreemass[torso] == pytest.approx(m.body_mass[1:].sum())
    assert m.opt.timestep == 0.002 and env.substeps().tolist() == [10, 12]  # round(0.025 / 0.002) = 12


def test_cheetah_stiffness_is_a_factor_on_the_xml_springs():
    env = make_env("DMCCheetahDefault-v0", num_envs=1, seed=0, joint_stiffness=0.5)
    assert env.mj_models[0].jnt_stiffness.tolist() == [0, 0, 0, 120, 90, 60, 90, 60, 30]


def test_mixed_timesteps_step_each_sub_env_as_alone():
    """Sub-envs of different timesteps (so different physics steps per action) in one batch:
    sub-env 0 (default) follows exactly the trajectory of a lone default env of the same seed."""
    space = context_space("DMCHopperDR-v0")
    ctx = torch.stack([space.default_tensor(), space.make(timestep=0.004)])
    both = make_env("DMCHopperDefault-v0", num_envs=2, seed=0)
    alone = make_env("DMCHopperDefault-v0", num_envs=1, seed=0)
    td2 = both.reset(TensorDict(context=ctx, batch_size=[2]))
    td1 = alone.reset()
    assert both.substeps().tolist() == [4, 5]
    actions = torch.rand(15, 2, 4, generator=torch.Generator().manual_seed(0)) * 2 - 1
    for a in actions:
        td2["action"], td1["action"] = a, a[:1]
        td2, td1 = both.step(td2)["next"], alone.step(td1)["next"]
        assert torch.equal(td2["observation"][:1], td1["observation"])
        assert not torch.equal(td2["observation"][0], td2["observation"][1])


def test_gravity_changes_the_fall():
    """Same initial state, zero actions: under half gravity the walker's torso has fallen less."""
    heights = {}
    for name in ("Default", "LowGravity"):
        env = make_env(f"DMCWalker{name}-v0", num_envs=1, seed=0)
        td = env.reset()
        z0 = td["observation"][0, 14].item()
        for _ in range(4):
            td["action"] = torch.zeros(1, 6)
            td = env.step(td)["next"]
        heights[name] = z0 - td["observation"][0, 14].item()
    assert heights["Default"] > 0 and 0 < heights["LowGravity"] < heights["Default"]


def test_domain_randomization_draws_contexts_inside_the_dr_ranges():
    env = make_env("DMCCheetahDR-v0", num_envs=8, seed=0)
    ctx = env.reset()["context"]
    space = env.context_space
    assert space.contains(ctx) and len({tuple(c) for c in ctx.tolist()}) == 8
    for i, model in enumerate(env.mj_models):
        assert model.opt.gravity[2] == pytest.approx(ctx[i, 0].item())
        assert model.opt.timestep == pytest.approx(ctx[i, 7].item())


def test_registry_ids_and_evaluation_suite():
    assert evaluation_suite("DMCWalkerDR-v0") == [f"DMCWalker{k}-v0" for k in (
        "Default", "Light", "Heavy", "Slippery", "WeakMotors", "LowGravity", "Hard")]
    spec = domain_of("DMCHopperHard-v0")
    assert spec.train_id == "DMCHopperDR-v0" and spec.objective_names == ("hop", "stand", "energy")
    assert spec.context_space.as_dict(spec.context_of("DMCHopperHard-v0"))["torso_mass"] == 2.0
    with pytest.raises(ValueError, match=r"'friction' is 20\.0.*\[0\.01, 10\.0\]"):
        make_env("DMCWalkerDefault-v0", friction=20.0)
    with pytest.raises(ValueError, match=r"'joint_damping' is -1\.0 \(row 0\); it must be >= 0"):
        make_env("DMCWalkerDefault-v0", joint_damping=-1.0, allow_extrapolation=True)
    with pytest.raises(ValueError, match="task must be one of"):
        make_env("DMCWalkerDefault-v0", task="fly")


def test_snapshot_resumes_exactly():
    env = make_env("DMCWalkerDR-v0", num_envs=3, seed=0, max_episode_steps=8)
    td = env.reset()
    actions = torch.rand(20, 3, 6, generator=torch.Generator().manual_seed(1)) * 2 - 1
    for a in actions[:5]:
        td["action"] = a
        _, td = env.step_and_maybe_reset(td)
    state, sampler, saved = env.simulator_state(), env.context_sampler.get_state(), td.clone()
    runs = []
    for _ in range(2):
        env.load_simulator_state(state)
        env.context_sampler.set_state(sampler)  # (the sampler's stream is the checkpoint's, not the simulator's)
        td, out = saved.clone(), []
        for a in actions[5:]:  # through an auto-reset (new contexts, new initial states)
            td["action"] = a
            step, td = env.step_and_maybe_reset(td)
            out.append(step["next", "reward"].clone())
        runs.append(torch.stack(out))
    assert torch.equal(runs[0], runs[1])


@pytest.mark.parametrize("env_id", ["DMCWalkerDefault-v0", "DMCHopperDefault-v0"])
def test_render_shows_the_sub_env(env_id):
    from morl_trl.envs.mujoco.render import gl_backend

    try:
        gl_backend()
    except RuntimeError as err:
        pytest.skip(str(err))
    env = make_env(env_id, num_envs=2, seed=0)
    env.reset()
    before = env.render(index=1, width=96, height=64)
    assert before.shape == (64, 96, 3) and before.dtype == np.uint8 and before.std() > 0
    for _ in range(5):
        env.rand_step()
    assert (env.render(index=1, width=96, height=64) != before).any()


def test_lean_auto_reset_matches_torchrl_path_under_dr():
    """The lean ``step_and_maybe_reset`` (partial resets, new DR contexts and timesteps) gives
    TorchRL's generic step + step_mdp + maybe_reset TensorDicts."""
    from tests.envs.test_auto_reset import _run_both

    make = lambda: make_env("DMCHopperDR-v0", num_envs=3, seed=1, max_episode_steps=7)  # noqa: E731
    assert _run_both(make, steps=16) == 6  # every sub-env ends at steps 7 and 14


def test_partial_step_advances_only_the_selected_sub_envs():
    env = make_env("DMCCheetahDefault-v0", num_envs=2, seed=0)
    td = env.reset()
    qpos = env.mj_data(1).qpos.copy()
    td["action"] = torch.full((2, 6), 0.5)
    td["_step"] = torch.tensor([True, False])
    env.step(td)
    assert np.array_equal(env.mj_data(1).qpos, qpos) and env.mj_data(0).time == pytest.approx(0.01)


def test_negative_joint_stiffness_is_rejected():
    with pytest.raises(ValueError, match=r"'joint_stiffness' is -2\.0 \(row 0\); it must be >= 0"):
        make_env("DMCHopperDefault-v0", joint_stiffness=-2.0, allow_extrapolation=True)
