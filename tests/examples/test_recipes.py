"""Every recipe in examples/ runs end to end (tiny settings) and prints its evaluations."""

import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
TINY = """
frames = 256
num_envs = 4
frames_per_batch = 64
updates_per_batch = 2
init_random_frames = 128
batch_size = 32
buffer_size = 1000
hidden = [16]
eval_interval = 256
eval_weights = 4
"""


@pytest.mark.parametrize(
    "script, args, env_id, first_context",
    [
        ("examples/envelope/envelope.py", [], "MOLunarLanderDR-v0", "Default"),
        ("examples/envelope/envelope.py", [], "MOLavaGridDR-v0", "CheckerBoard"),
        ("examples/actor_critic/actor_critic.py", ["--algo", "capql"], "MOHopperDR-v5", "Default"),
        ("examples/actor_critic/actor_critic.py", ["--algo", "mosac"], "MOHalfCheetahDR-v5", "Default"),
    ],
)
def test_recipe_runs(tmp_path, script, args, env_id, first_context):
    if "LunarLander" in env_id:
        pytest.importorskip("Box2D")
    elif "Hopper" in env_id or "HalfCheetah" in env_id:
        pytest.importorskip("mujoco")
    cfg = tmp_path / "tiny.toml"
    cfg.write_text(f'env_id = "{env_id}"\n' + TINY)
    out = subprocess.run([sys.executable, str(ROOT / script), *args, "--config", str(cfg)],
                         capture_output=True, text=True, timeout=300, cwd=ROOT)
    assert out.returncode == 0, out.stderr[-3000:]
    lines = [line for line in out.stdout.splitlines() if line.startswith("frames")]
    assert len(lines) == 1 and f"hypervolume: {first_context}=" in lines[0]
