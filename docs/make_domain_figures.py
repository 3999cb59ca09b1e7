"""Renders each domain's evaluation suite with env.render() into docs/domains/<domain>.png.

    python docs/make_domain_figures.py [lunar_lander hopper halfcheetah humanoid mario]

Each panel is one evaluation context after a few steps of a fixed action sequence (seed 0), so
the picture shows the body or lander in its context, not a trained policy.
"""

import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import torch

from morl_trl.envs import evaluation_suite, make_env

DOMAINS = {
    "lunar_lander": ("MOLunarLanderDR-v0", 40),
    "hopper": ("MOHopperDR-v5", 20),
    "halfcheetah": ("MOHalfCheetahDR-v5", 20),
    "humanoid": ("MOHumanoidDR-v5", 10),
    "mario": ("MOSuperMarioBrosZeroShot-v2", 30),
}


def render_suite(name: str) -> Path:
    train_id, steps = DOMAINS[name]
    ids = evaluation_suite(train_id)
    cols = 4
    rows = -(-len(ids) // cols)
    fig, axes = plt.subplots(rows, cols, figsize=(3.2 * cols, 2.6 * rows), squeeze=False)
    for ax, env_id in zip(axes.flat, ids):
        env = make_env(env_id, num_envs=1, seed=0)
        td = env.reset()
        spec = env.full_action_spec[env.action_key]
        for _ in range(steps):
            if spec.dtype in (torch.int64, torch.int32):
                action = torch.zeros(spec.shape, dtype=spec.dtype)  # noop / the first action
            else:
                action = torch.zeros(spec.shape)
            td = env.step(td.set(env.action_key, action))["next"]
        ax.imshow(env.render(0))
        short = env_id.replace(train_id.split("DR")[0].split("ZeroShot")[0], "").rsplit("-v", 1)[0].lstrip("-")
        ax.set_title(short or env_id, fontsize=10)
        ax.axis("off")
        env.close()
    for ax in list(axes.flat)[len(ids):]:
        ax.axis("off")
    fig.tight_layout()
    out = Path(__file__).parent / "domains" / f"{name}.png"
    fig.savefig(out, dpi=60)
    plt.close(fig)
    return out


if __name__ == "__main__":
    for name in sys.argv[1:] or list(DOMAINS):
        try:
            print(render_suite(name))
        except Exception as err:  # a domain whose renderer or extra is missing here
            print(f"{name}: not rendered ({type(err).__name__}: {err})")
