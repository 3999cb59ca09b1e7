"""One clip per evaluation context: a policy's episode under a chosen weight, through TorchRL.

The env of each context is the policy stack of evaluation (``env_factory``: the env with the
policy's observation transforms) with ``PreferenceConditioning(mode="given")`` (the weight),
TorchRL's :class:`~torchrl.record.PixelRenderTransform` (``env.render(index=None)``: the
``"pixels"`` entry) and :class:`~torchrl.record.VideoRecorder` writing to a TorchRL logger.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import torch
from tensordict import TensorDict
from torchrl.envs import EnvBase, TransformedEnv
from torchrl.envs.utils import ExplorationType, set_exploration_type
from torchrl.record import PixelRenderTransform, VideoRecorder

from morl_trl.preferences import check_simplex
from morl_trl.transforms import PreferenceConditioning

__all__ = ["record_context_videos"]


def record_context_videos(
    policy,
    env_factory: Callable[[str], EnvBase],
    contexts: Sequence[str],
    logger,
    *,
    weight: Sequence[float] | torch.Tensor | None = None,
    step: int = 0,
    max_steps: int | None = None,
    exploration_type: ExplorationType = ExplorationType.DETERMINISTIC,
    fps: int = 30,
    preference_key: str = "preference",
) -> dict[str, int]:
    """Run one episode per context with ``weight`` (default equal weights) and log its clip
    under the context's name (``logger.log_video(context, ..., step=step)``).

    ``env_factory(context)`` builds a one-sub-env env of that context with the policy's
    observation transforms. Returns the number of frames of each clip.
    """
    frames = {}
    for ctx in contexts:
        base = env_factory(ctx)
        if base.batch_size != torch.Size([1]):
            raise ValueError(f"env_factory({ctx!r}) gave batch size {tuple(base.batch_size)}; a video needs [1]")
        k = int(base.full_reward_spec[base.reward_key].shape[-1])
        w = torch.full((k,), 1.0 / k) if weight is None else torch.as_tensor(weight, dtype=torch.float32)
        if w.shape != (k,):
            raise ValueError(f"the video weight has {w.numel()} entries; the domain has {k} objectives")
        check_simplex(w, k, name="video weight")
        recorder = VideoRecorder(logger, tag=ctx, in_keys=["pixels"], skip=1, make_grid=False, fps=fps)
        env = base if isinstance(base, TransformedEnv) else TransformedEnv(base)
        env.append_transform(PreferenceConditioning(k, mode="given", preference_key=preference_key))
        env.append_transform(PixelRenderTransform(index=None))
        env.append_transform(recorder)
        horizon = max_steps or getattr(env.base_env, "max_episode_steps", 1000)
        with torch.no_grad(), set_exploration_type(exploration_type):
            td = env.reset(TensorDict({preference_key: w.expand(1, k)}, batch_size=[1]))
            out = env.rollout(horizon, policy, tensordict=td, auto_reset=False, break_when_any_done=True)
        frames[ctx] = len(recorder.obs)
        recorder.dump(step=step)
        env.close()
    return frames
