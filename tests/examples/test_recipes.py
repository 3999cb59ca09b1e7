"""The example configs resolve, and the custom loop in examples/ runs end to end."""

import subprocess
import sys
from pathlib import Path

import pytest

from morl_trl.recipes import resolve_config

ROOT = Path(__file__).resolve().parents[2]


@pytest.mark.parametrize(
    "algo, path, env_id, frames",
    [
        ("envelope", "examples/envelope/lunar_lander_quick.toml", "MOLunarLanderDR-v0", 60_000),
        ("envelope", "examples/envelope/lava_grid_quick.toml", "MOLavaGridDR-v0", 60_000),
        ("envelope", "examples/envelope/lunar_lander_paper.toml", "MOLunarLanderDR-v0", 3_000_000),
        ("capql", "examples/actor_critic/hopper_quick.toml", "MOHopperDR-v5", 20_000),
        ("capql", "examples/actor_critic/hopper_paper.toml", "MOHopperDR-v5", 3_000_000),
        ("mosac", "examples/actor_critic/half_cheetah_quick.toml", "MOHalfCheetahDR-v5", 20_000),
        ("mosac", "examples/actor_critic/half_cheetah_paper.toml", "MOHalfCheetahDR-v5", 5_000_000),
        ("gpi_ls", "examples/gpi/lunar_lander_quick.toml", "MOLunarLanderDR-v0", 60_000),
        ("gpi_ls", "examples/gpi/lava_grid_quick.toml", "MOLavaGridDR-v0", 60_000),
        ("gpi_pd", "examples/gpi/lunar_lander_paper.toml", "MOLunarLanderDR-v0", 3_000_000),
    ],
)
def test_example_configs_resolve(algo, path, env_id, frames):
    cfg = resolve_config(algo, "MOLavaGridDR-v0", config_file=ROOT / path)
    assert (cfg.env_id, cfg.frames) == (env_id, frames)


def test_quick_config_file_equals_the_quick_preset():
    from_file = resolve_config("envelope", "MOLunarLanderDR-v0", config_file=ROOT / "examples/envelope/lunar_lander_quick.toml")
    assert from_file == resolve_config("envelope", "MOLunarLanderDR-v0", quick=True)


def test_gpi_quick_config_file_equals_the_quick_preset():
    path = ROOT / "examples/gpi/lunar_lander_quick.toml"
    assert resolve_config("gpi_ls", "MOLunarLanderDR-v0", config_file=path) == \
        resolve_config("gpi_ls", "MOLunarLanderDR-v0", quick=True)


def test_custom_trainer_runs():
    out = subprocess.run([sys.executable, str(ROOT / "examples/custom_trainer.py"), "--frames", "1536",
                          "--eval-weights", "3"], capture_output=True, text=True, timeout=900, cwd=ROOT)  # (a hang guard)
    assert out.returncode == 0, out.stderr[-3000:]
    (line,) = [line for line in out.stdout.splitlines() if line.startswith("frames")]
    assert line.startswith("frames 1536: hypervolume per context CheckerBoard=")
    assert line.count("=") == 8
