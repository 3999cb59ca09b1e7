"""Every MO-Gymnasium id our install builds trains from the command line with no extra flag (issue 45):
a reference point by the documented rule (morl_trl.envs.ref_point), a run of 3,000 frames for the
discrete and continuous kinds in the default suite (the image id, minecart-rgb-v0, steps and
resolves here, trains in the slow sweep), every id in the slow one; the ids skipped, and why."""

from __future__ import annotations

import math

import pytest

pytest.importorskip("mo_gymnasium")

import gymnasium  # noqa: E402
import mo_gymnasium  # noqa: E402, F401  (registers its ids)
import torch  # noqa: E402

from morl_trl.cli import main  # noqa: E402
from morl_trl.envs import domain_of, make_env  # noqa: E402
from morl_trl.envs.ref_point import MO_GYMNASIUM_REF_POINTS, bounds_reference_point, rollout_margin  # noqa: E402
from morl_trl.reporting.report import hv_ratio_note  # noqa: E402

MO_IDS = sorted(k for k, v in gymnasium.registry.items() if str(v.entry_point).startswith("mo_gymnasium"))

#: the ids this install cannot build, and why (test_skipped_ids_do_not_build keeps the list true)
SKIPPED = {
    "mo-highway-v0": "needs highway-env, which is not installed (MO-Gymnasium's highway extra)",
    "mo-highway-fast-v0": "needs highway-env, which is not installed (MO-Gymnasium's highway extra)",
    "mo-supermario-v0": "gym-super-mario-bros / nes-py fail under NumPy 2 (OverflowError in nes_py); "
                        "morl_trl's own MO-SuperMarioBros domain runs instead",
    "water-reservoir-v0": "its action Box is [0, inf): our continuous methods squash actions into finite bounds, "
                          "so it is refused with a ValueError saying so",
}
BUILDABLE = [i for i in MO_IDS if i not in SKIPPED]

#: the algorithm each action-space kind trains with in these tests
DEFAULT_ALGO = {"discrete": "envelope", "continuous": "capql"}


def _kind(env_id: str) -> str:
    env = mo_gymnasium.make(env_id)
    try:
        return "discrete" if isinstance(env.action_space, gymnasium.spaces.Discrete) else "continuous"
    finally:
        env.close()


def _tiny(env_id: str) -> list[str]:
    """Few updates, small networks, one evaluation episode per weight (as many weights as objectives)."""
    k = len(domain_of(env_id).objective_names)
    return [f"eval_weights={k}", "eval_episodes=1", "eval_random_baseline=false", "hidden=[32,32]", "batch_size=32",
            "buffer_size=512", "init_random_frames=100", "num_envs=1", "frames_per_batch=500", "updates_per_batch=1",
            "--logger", "none", "--no-progress"]


def _train(env_id: str, tmp_path, capsys, frames: str = "3000") -> tuple[int, str, str]:
    capsys.readouterr()
    algo = DEFAULT_ALGO[_kind(env_id)]
    rc = main(["train", algo, env_id, "--frames", frames, "--run-dir", str(tmp_path / "run"), *_tiny(env_id)])
    out = capsys.readouterr()
    return rc, out.out, out.err


def test_every_mo_gymnasium_id_is_built_or_listed_as_skipped():
    assert len(MO_IDS) >= 30 and "four-room-v0" in BUILDABLE and "minecart-rgb-v0" in BUILDABLE
    assert set(SKIPPED) <= set(MO_IDS)


@pytest.mark.parametrize("env_id", sorted(SKIPPED))
def test_skipped_ids_do_not_build(env_id):
    try:
        make_env(env_id, num_envs=1).close()
    except (ImportError, ValueError, OverflowError):
        return
    pytest.fail(f"{env_id} builds now: remove it from SKIPPED ({SKIPPED[env_id]})")


def test_the_reference_point_rule():
    # rule 1: MORL-Baselines' point
    assert domain_of("deep-sea-treasure-v0").hv_ref_point == (0.0, -25.0)
    assert domain_of("mo-lunar-lander-continuous-v3").hv_ref_point == (-101.0, -1001.0, -101.0, -101.0)
    # rule 2: horizon x min(reward_space low, 0) - 1
    rg = domain_of("resource-gathering-v0")  # low (-1, 0, 0), 100 steps
    assert rg.hv_ref_point == (-101.0, -1.0, -1.0)
    assert rg.hv_ref_point_source == "derived: horizon 100 x min(reward_space low, 0) - 1 per objective"
    assert domain_of("four-room-v0").hv_ref_point == (-1.0, -1.0, -1.0)  # low 0: -1 whatever the horizon
    assert domain_of("mo-mountaincar-v0").hv_ref_point == (-201.0, -201.0, -201.0)  # low -1, 200 steps
    assert domain_of("fishwood-v0").hv_ref_point == (-1.0, -1.0)  # no horizon, low 0
    assert bounds_reference_point([-1.0, 0.5, -math.inf], 50) == [-51.0, -1.0, None]
    # rule 3: the lowest return of 5 random episodes, floor(1.1 min(m, 0)) - 1
    assert (rollout_margin(-250.4), rollout_margin(-0.5), rollout_margin(40.0)) == (-277.0, -2.0, -1.0)
    bottles = domain_of("breakable-bottles-v0")  # objective 0's low is -inf
    assert bottles.hv_ref_point[1:] == (-1.0, -101.0) and bottles.hv_ref_point[0] <= -2
    assert "for objectives [0] (reward_space low -inf)" in bottles.hv_ref_point_source


@pytest.mark.parametrize("env_id", BUILDABLE)
def test_every_buildable_id_has_a_finite_reference_point_and_its_source(env_id):
    spec = domain_of(env_id)
    assert len(spec.hv_ref_point) == len(spec.objective_names) >= 2
    assert all(math.isfinite(v) for v in spec.hv_ref_point)
    source = spec.hv_ref_point_source
    assert source.startswith("derived: ") or source == MO_GYMNASIUM_REF_POINTS[env_id][1]


@pytest.mark.parametrize("env_id", ["resource-gathering-v0", "mo-mountaincarcontinuous-v0"],
                         ids=["discrete", "continuous"])
def test_train_3000_frames_with_no_extra_flag(env_id, tmp_path, capsys):
    rc, out, err = _train(env_id, tmp_path, capsys)
    assert rc == 0, err
    point = domain_of(env_id).hv_ref_point
    assert f"reference point {list(point)} (" in out  # printed at the start
    assert f"reference point {list(point)} (" in (tmp_path / "run" / "report.md").read_text()
    assert "Frames: 3000" in (tmp_path / "run" / "report.md").read_text()
    assert "Gym has been unmaintained" not in err and "precision lowered" not in err


def test_image_observations_build_and_configure(capsys):
    """minecart-rgb-v0, the one image id ([480, 480, 3] frames, rendered at ~8 ms a step): it steps as
    [C, H, W] uint8 area-averaged to 84 x 84 (at 480 x 480 the CNN's head had 100M weights: 1 frame/s)
    and the command line resolves its run; its 3,000-frame run is in the slow sweep."""
    env = make_env("minecart-rgb-v0", num_envs=1, seed=0)
    td = env.rollout(2, break_when_any_done=False)
    env.close()
    assert td["observation"].shape == (1, 2, 3, 84, 84) and td["observation"].dtype == torch.uint8
    assert 0 < td["observation"].float().mean() < 255
    assert main(["train", "envelope", "minecart-rgb-v0", "--frames", "3k", "--print-config"]) == 0
    assert "frames = 3000 " in capsys.readouterr().out


@pytest.mark.slow
@pytest.mark.parametrize("env_id", BUILDABLE)
def test_every_buildable_id_trains_3000_frames(env_id, tmp_path, capsys):
    rc, _, err = _train(env_id, tmp_path, capsys)
    assert rc == 0, err
    assert "Frames: 3000" in (tmp_path / "run" / "report.md").read_text()


def test_a_hypervolume_ratio_above_one_is_explained():
    """The random policy's hv_ratio 1.073 on resource-gathering (issue 45): MO-Gymnasium's front holds
    expected returns; one lucky episode (gold and gem, no attack: (0, 1, 1)) dominates the expected
    (-0.1, 0.9, 0.9) of the policy that fetches both."""
    from types import SimpleNamespace

    from morl_trl.metrics import hypervolume

    true = domain_of("resource-gathering-v0").true_front(1.0)
    ratio = hypervolume([[0.0, 1.0, 1.0]], [-1.0, -1.0, -1.0]) / hypervolume(true, [-1.0, -1.0, -1.0])
    assert round(ratio, 3) == 1.073
    ours = SimpleNamespace(metric=lambda name: {"resource-gathering-v0": ratio if name == "hv_ratio" else None})
    note = hv_ratio_note([ours, None], episodes=1)
    assert note.startswith("hv_ratio above 1 (1.073): the true front (MO-Gymnasium's pareto_front) holds the "
                           "expected returns of the best policies, while each evaluated point is the mean return of "
                           "1 episode per weight.")
    below = SimpleNamespace(metric=lambda name: {"resource-gathering-v0": 0.5})
    assert hv_ratio_note([below], episodes=5) is None


def test_dependency_noise_is_dropped_in_our_env_builds_only():
    """gym's "unmaintained" banner (printed when TorchRL's MOGymEnv imports gym) and gymnasium's Box
    precision warnings are dropped while morl_trl builds a MO-Gymnasium env (make_gym_env and the
    TorchRL wrapper run inside quiet_gym); the user's own gymnasium.make warns as it always did.
    (A fresh process without torch: the banner prints once per process.)"""
    import subprocess
    import sys

    code = ("import sys, warnings\nwarnings.simplefilter('always')\n"
            "from morl_trl._quiet import quiet_gym\nimport mo_gymnasium\n"
            "with quiet_gym():\n    mo_gymnasium.make('resource-gathering-v0').close()\n"
            "print('--- the user builds one ---', file=sys.stderr, flush=True)\n"
            "mo_gymnasium.make('resource-gathering-v0').close()\n"
            "print('gym' in sys.modules, 'torch' in sys.modules)\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "True False"  # quiet_gym imported gym (its banner dropped), not torch
    ours, user = out.stderr.split("--- the user builds one ---")
    assert "unmaintained" not in ours and "precision lowered" not in ours
    assert "Box low's precision lowered by casting" in user
    plain = subprocess.run([sys.executable, "-c", "import gym"], capture_output=True, text=True, timeout=300)
    assert "Gym has been unmaintained since 2022" in plain.stderr  # (what quiet_gym dropped above)
