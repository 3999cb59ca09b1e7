"""Renders the eight MO-LavaGrid evaluation maps (docs/lava_grid_maps.png) with env.render()."""

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt

from morl_trl.envs import evaluation_suite, make_env

ids = evaluation_suite("MOLavaGridDR-v0")
fig, axes = plt.subplots(2, 4, figsize=(12, 6.4))
for ax, env_id in zip(axes.flat, ids):
    env = make_env(env_id, num_envs=1)
    env.reset()
    ax.imshow(env.render(0, 24))
    ax.set_title(env_id.replace("MOLavaGrid", "").replace("-v0", ""), fontsize=11)
    ax.axis("off")
fig.tight_layout()
out = Path(__file__).with_name("lava_grid_maps.png")
fig.savefig(out, dpi=80)
print(out)
