"""Every domain renders rgb_array for a chosen sub-env; TorchRL's PixelRenderTransform works on them."""

import numpy as np
import pytest
import torch
from torchrl.record import PixelRenderTransform

from morl_trl.envs import make_env


@pytest.mark.parametrize("env_id, shape", [("MOLavaGridRoom-v0", (208, 208, 3)),
                                           ("MOLunarLanderDefault-v0", (400, 600, 3))])
def test_render_one_sub_env_or_all(env_id, shape):
    if "LunarLander" in env_id:
        pytest.importorskip("Box2D")
    env = make_env(env_id, num_envs=2, seed=0)
    env.reset()
    img = env.render()
    assert img.shape == shape and img.dtype == np.uint8
    assert env.render(index=None).shape == (2, *shape)
    assert np.array_equal(env.render(-1), env.render(1))
    with pytest.raises(ValueError, match="index 2 is out of range for 2 sub-envs"):
        env.render(2)
    with pytest.raises(ValueError, match="render mode 'human' is not supported"):
        env.render(mode="human")


def test_pixel_render_transform_records_every_sub_env():
    env = make_env("MOLavaGridDR-v0", num_envs=3, seed=0).append_transform(PixelRenderTransform(index=None))
    td = env.rollout(4, break_when_any_done=False)
    assert td["pixels"].shape == (3, 4, 208, 208, 3) and td["pixels"].dtype == torch.uint8


def _mujoco_renders():
    pytest.importorskip("mujoco")
    from morl_trl.envs.mujoco.render import gl_backend

    try:
        return gl_backend()
    except RuntimeError as err:
        pytest.skip(str(err))


@pytest.mark.parametrize("env_id", ["MOHopperDefault-v5", "MOHalfCheetahDefault-v5"])
def test_mujoco_render_changes_between_steps(env_id):
    _mujoco_renders()
    env = make_env(env_id, num_envs=2, seed=0)
    env.reset()
    before = env.render(index=1, width=96, height=64)
    assert before.shape == (64, 96, 3) and before.dtype == np.uint8
    for _ in range(5):
        env.rand_step()
    after = env.render(index=1, width=96, height=64)
    assert after.shape == (64, 96, 3) and (before != after).any()
    assert env.render(index=None, width=32, height=32).shape == (2, 32, 32, 3)
