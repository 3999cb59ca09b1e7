"""Each domain's f_SORL (``DomainSpec.sorl``, the paper's appendix) against what its env emits as
``original_reward``: step by step, the weighted sum of the vector reward plus the offset, and
where the spec says it is not exact, exactly the documented difference."""

import importlib.util

import pytest
import torch

from morl_trl.envs import domain_of, make_env


def rollout(env_id, steps, seed=0, num_envs=8, **kwargs):
    env = make_env(env_id, num_envs=num_envs, seed=seed, **kwargs)
    torch.manual_seed(seed)
    td = env.rollout(steps, break_when_any_done=False)  # random actions, auto-reset
    return td["next", "reward"].double(), td["next", "original_reward"].double().squeeze(-1), td


@pytest.mark.parametrize(
    ("env_id", "paper"),
    [
        ("MOHopperDR-v5", "1.5 v_x + 0.001 c + h"),
        ("MOHalfCheetahDR-v5", "1.0 v_x + 0.1 c"),
        ("MOHumanoidDR-v5", "1.25 v_x + 0.001 c + 2.0 h"),
        ("MOLavaGridDR-v0", ""),
    ],
)
def test_original_reward_is_the_spec_weighted_sum_of_the_vector_reward(env_id, paper):
    if "Lava" not in env_id and importlib.util.find_spec("mujoco") is None:
        pytest.skip("needs the mujoco extra")
    sorl = domain_of(env_id).sorl
    assert sorl.paper == paper and sorl.exact
    reward, original, td = rollout(env_id, 200)
    torch.testing.assert_close(sorl.scalarize(reward), original, rtol=1e-5, atol=1e-4)
    if env_id == "MOHopperDR-v5":  # episodes terminated: the healthy term is in the terminal step too
        assert td["next", "terminated"].any()


def test_hopper_forward_weight_is_what_was_measured_not_the_paper_text():
    sorl = domain_of("MOHopperDR-v5").sorl
    assert sorl.weights == (1.0, 0.0, 0.001) and sorl.offset == -0.001
    assert "1.5 v_x" in sorl.note and "forward_reward_weight=1.0" in sorl.note


@pytest.mark.parametrize("env_id", ["MOLunarLanderDR-v0", "MOLunarLanderContinuousDR-v0"])
def test_lunar_lander_differs_only_on_the_terminating_step(env_id):
    if importlib.util.find_spec("Box2D") is None:
        pytest.skip("needs the box2d extra")
    sorl = domain_of(env_id).sorl
    assert sorl.weights == (1.0, 1.0, 0.3, 0.03) and not sorl.exact
    reward, original, td = rollout(env_id, 300, num_envs=6)
    terminal = td["next", "terminated"].squeeze(-1)
    assert terminal.any() and (~terminal).any()
    torch.testing.assert_close(sorl.scalarize(reward)[~terminal], original[~terminal], rtol=1e-5, atol=1e-4)
    # Gymnasium replaces the terminal step's reward with the landing term alone
    torch.testing.assert_close(original[terminal], reward[..., 0][terminal])
    assert set(original[terminal].abs().tolist()) == {100.0}


@pytest.mark.slow  # ~25 s: emulator start-up
@pytest.mark.mario
def test_mario_f_sorl_is_the_forward_objective_over_0_03():
    if importlib.util.find_spec("nes_py") is None or importlib.util.find_spec("gym_super_mario_bros") is None:
        pytest.skip("needs the mario extra")
    sorl = domain_of("MOSuperMarioBros-1-2-v2").sorl
    assert sorl.paper == "f + t + d" and not sorl.exact
    reward, original, _ = rollout("MOSuperMarioBros-1-2-v2", 60, num_envs=2, death_penalty_on_dying=True)
    torch.testing.assert_close(sorl.scalarize(reward), original, rtol=1e-4, atol=1e-3)


def test_every_domain_with_original_reward_in_the_paper_has_a_sorl():
    for env_id in ("MOHopperDR-v5", "MOHalfCheetahDR-v5", "MOHumanoidDR-v5", "MOLunarLanderDR-v0",
                   "MOLunarLanderContinuousDR-v0", "MOSuperMarioBrosZeroShot-v2", "MOLavaGridDR-v0"):
        spec = domain_of(env_id)
        assert spec.sorl is not None and len(spec.sorl.weights) == spec.num_objectives


def test_a_sorl_with_the_wrong_number_of_weights_is_refused():
    from dataclasses import replace

    spec = domain_of("MOHopperDR-v5")
    with pytest.raises(ValueError, match="f_SORL has 2 weights for 3 objectives"):
        replace(spec, sorl=replace(spec.sorl, weights=(1.0, 0.1)))
