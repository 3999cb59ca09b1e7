"""Every id as a Gymnasium / MO-Gymnasium environment (morl_trl.gym)."""

import re
import subprocess
import sys
import warnings

import numpy as np
import pytest

gymnasium = pytest.importorskip("gymnasium")
mo_gymnasium = pytest.importorskip("mo_gymnasium")

from gymnasium.utils.env_checker import check_env  # noqa: E402

import morl_trl.gym  # noqa: E402  (registers morl_trl/<id>)
from morl_trl.envs import list_envs  # noqa: E402
from morl_trl.gym import MOGymnasiumEnv, register_gymnasium_envs  # noqa: E402

IDS = ["MOLunarLanderDR-v0", "MOLavaGridDR-v0", "MOHopperDR-v5"]
_NEEDS = {"MOLunarLanderDR-v0": "Box2D", "MOHopperDR-v5": "mujoco"}


def _make(env_id, **kwargs):
    if env_id in _NEEDS:
        pytest.importorskip(_NEEDS[env_id])
    return mo_gymnasium.make(f"morl_trl/{env_id}", **kwargs)


def test_every_id_is_registered_under_the_namespace():
    registered = register_gymnasium_envs()  # again: idempotent
    assert registered == [f"morl_trl/{i}" for i in list_envs()]
    assert all(g in gymnasium.registry for g in registered)


@pytest.mark.parametrize("env_id", IDS)
def test_passes_gymnasiums_env_checker_with_a_vector_reward(env_id):
    env = _make(env_id)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # (the checker warns that the reward is a vector and the Box unbounded)
        check_env(env.unwrapped)
    k = len(env.unwrapped.objective_names)
    assert env.unwrapped.reward_space == gymnasium.spaces.Box(-np.inf, np.inf, (k,), np.float32)
    obs, info = env.reset(seed=0)
    assert obs in env.observation_space and info["context"].dtype == np.float32
    obs, reward, terminated, truncated, info = env.step(env.action_space.sample())
    assert reward.shape == (k,) and reward.dtype == np.float32
    assert isinstance(terminated, bool) and isinstance(truncated, bool)
    assert {"context", "original_reward"} <= set(info)
    env.close()


@pytest.mark.parametrize("env_id", IDS)
def test_same_seed_same_episode(env_id):
    def episode(seed):
        env = _make(env_id)
        env.action_space.seed(seed)
        obs, info = env.reset(seed=seed)
        out = [obs, info["context"]]
        for _ in range(20):
            obs, reward, *_ = env.step(env.action_space.sample())
            out += [obs, reward]
        env.close()
        return out

    a, b, c = episode(3), episode(3), episode(4)
    assert all(np.array_equal(x, y) for x, y in zip(a, b))
    assert not all(np.array_equal(x, y) for x, y in zip(a, c))


def test_contexts_through_reset_options():
    env = _make("MOLunarLanderDR-v0")
    u = env.unwrapped
    _, info = env.reset(seed=0, options={"context": {"gravity": -5.0, "wind_power": 0.0}})
    named = dict(zip(u.context_names, info["context"]))
    assert named["gravity"] == -5.0 and named["wind_power"] == 0.0
    vector = u.context_space.make(gravity=-11.0)
    _, info = env.reset(options={"context": vector.numpy()})
    np.testing.assert_array_equal(info["context"], vector.numpy())
    with pytest.raises(ValueError, match="gravityy"):
        env.reset(options={"context": {"gravityy": 1.0}})
    with pytest.raises(ValueError, match="unknown reset option"):
        env.reset(options={"contxt": {}})
    fixed = _make("MOLunarLanderHard-v0")
    assert np.array_equal(fixed.reset(seed=0)[1]["context"], fixed.reset(seed=1)[1]["context"])


def test_mo_gymnasium_wrappers():
    from mo_gymnasium.wrappers import LinearReward, MORecordEpisodeStatistics

    env = LinearReward(MORecordEpisodeStatistics(_make("MOLavaGridRoom-v0"), gamma=0.99),
                       weight=np.array([0.5, 0.5], dtype=np.float32))
    env.reset(seed=0)
    env.action_space.seed(0)
    done, steps = False, 0
    while not done:
        _, reward, terminated, truncated, info = env.step(env.action_space.sample())
        done, steps = terminated or truncated, steps + 1
        assert np.isscalar(reward) and info["vector_reward"].shape == (2,)
    assert info["episode"]["r"].shape == (2,) and info["episode"]["l"] == steps


def test_lava_grid_renders_rgb_arrays():
    env = gymnasium.make("morl_trl/MOLavaGridSnake-v0", render_mode="rgb_array")
    env.reset(seed=0)
    frame = env.render()
    assert frame.dtype == np.uint8 and frame.ndim == 3 and frame.shape[-1] == 3
    with pytest.raises(ValueError, match="render_mode"):
        MOGymnasiumEnv("MOLavaGridSnake-v0", render_mode="human")


def test_gymnasium_make_needs_no_import_with_the_module_prefix():
    code = ("import gymnasium; e = gymnasium.make('morl_trl.gym:morl_trl/MOLavaGridDR-v0'); "
            "e.reset(seed=0); print(e.step(0)[1].shape)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=600)  # (a hang guard)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "(2,)"


@pytest.mark.parametrize("action, message", [
    (1.5, "discrete actions must be integers in [0, 3); got 1.5"),
    (True, "discrete actions must be integers in [0, 3); got a torch.bool tensor"),
    (float("nan"), "discrete actions must be integers in [0, 3); got nan"),
    (3, "action 3 is out of the action space [0, 3)"),
    ("left", "MOLavaGridDR-v0: action 'left' is not numeric; valid: Discrete(3)"),
    ([1, 2], "MOLavaGridDR-v0: action has shape (2,); valid: Discrete(3) (shape ())"),
])
def test_discrete_actions_are_checked_as_the_torchrl_env_checks_them(action, message):
    from morl_trl.gym import MOGymnasiumEnv

    env = MOGymnasiumEnv("MOLavaGridDR-v0")
    env.reset(seed=0)
    with pytest.raises(ValueError, match=re.escape(message)):
        env.step(action)
    obs, reward, *_ = env.step(np.int64(2))  # a valid action still steps
    assert reward.shape == (2,)


@pytest.mark.parametrize("action, message", [
    (np.full(3, np.nan), "action contains NaN or inf"),
    (np.full(3, 2.0), "action out of its bounds"),
    (np.ones(2), "MOHopperDR-v5: action has shape (2,); valid: Box(-1.0, 1.0, (3,), float32) (shape (3,))"),
    (np.array([True, False, True]), "continuous actions must be real numbers; got a torch.bool tensor"),
])
def test_continuous_actions_are_checked(action, message):
    pytest.importorskip("mujoco")
    from morl_trl.gym import MOGymnasiumEnv

    env = MOGymnasiumEnv("MOHopperDR-v5")
    env.reset(seed=0)
    with pytest.raises(ValueError, match=re.escape(message)):
        env.step(action)
