"""The env state a checkpoint captures continues episodes exactly (or says it cannot)."""

from __future__ import annotations

import pytest
import torch

from morl_trl.envs import make_env
from morl_trl.recipes import resolve_config, train
from morl_trl.runs.env_state import can_snapshot, env_state, load_env_state
from morl_trl.transforms import compose_training_env


def _replays_exactly(env_id: str, before: int, after: int, history_len: int) -> int:
    """Step ``before`` steps, snapshot (env state + the carried TensorDict + the action stream),
    step ``after`` more, restore, step them again: every output must be the same. Returns the
    number of episodes that ended after the snapshot."""
    env = compose_training_env(make_env(env_id, num_envs=3, seed=0), gamma=0.99, history_len=history_len,
                               preference_seed=1)
    assert can_snapshot(env)
    spec = env.full_action_spec["action"]
    gen = torch.Generator().manual_seed(0)

    def act(td):
        if spec.dtype == torch.long:
            return td.set("action", torch.randint(0, spec.space.n, spec.shape, generator=gen))
        return td.set("action", (torch.rand(spec.shape, generator=gen) * 2 - 1) * 0.4)

    td = env.reset()
    for _ in range(before):
        _, td = env.step_and_maybe_reset(act(td))
    snap, carried, gen_state = env_state(env), td.clone(), gen.get_state()
    first = []
    for _ in range(after):
        out, td = env.step_and_maybe_reset(act(td))
        first.append(out.clone())
    load_env_state(env, snap)
    td = carried
    gen.set_state(gen_state)
    for i in range(after):
        out, td = env.step_and_maybe_reset(act(td))
        for key in out.keys(True, True):
            assert torch.equal(out[key], first[i][key]), f"{env_id}: {key} differs {i} steps after the restore"
    return sum(int(o["next", "done"].sum()) for o in first)


def test_lava_grid_snapshot_continues_exactly():
    assert _replays_exactly("MOLavaGridDR-v0", before=100, after=400, history_len=0) >= 3  # through resets


@pytest.mark.parametrize("env_id, after", [("MOHopperDR-v5", 300), ("MOHumanoidDR-v5", 150)])
def test_mujoco_snapshot_continues_exactly(env_id, after):
    pytest.importorskip("mujoco")
    assert _replays_exactly(env_id, before=30, after=after, history_len=2) >= 1


def test_a_domain_without_snapshots_resumes_with_fresh_episodes(tmp_path):
    pytest.importorskip("Box2D")
    run = tmp_path / "run"
    cfg = resolve_config(
        "envelope", "MOLunarLanderDR-v0", run_dir=str(run), frames=128, num_envs=4, frames_per_batch=64,
        init_random_frames=64, updates_per_batch=1, batch_size=16, hidden=(16,), eval_interval=128, eval_weights=4,
        checkpoint_interval=64, buffer_size=1024, eval_contexts=("MOLunarLanderDefault-v0",), progress=False,
        eval_random_baseline=False)
    train(cfg)
    assert not can_snapshot(make_env("MOLunarLanderDR-v0"))
    cfg.frames = 192
    train(cfg, resume=run)
    log = (run / "log.txt").read_text()
    assert "resumed with fresh episodes: MO-LunarLander cannot snapshot its simulator" in log
    frames = [line.split(",")[0] for line in (run / "eval" / "metrics.csv").read_text().splitlines()[1:]]
    assert frames == ["0", "128", "192"]
