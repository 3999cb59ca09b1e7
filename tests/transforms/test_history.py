import pytest
import torch
from tensordict import TensorDict
from torchrl.data import Bounded, Unbounded
from torchrl.envs import TransformedEnv
from torchrl.envs.utils import check_env_specs, step_mdp
from torchrl.testing.mocking_classes import DiscreteActionConvMockEnv, DiscreteActionVecMockEnv

from morl_trl.transforms import StateActionHistory
from tests.mocks import ToyContextEnv
from tests.transforms.helpers import ScriptedPolicy, ToyContinuousEnv, episode_starts, history_reference


def test_paper_layout_first_steps_concrete_values():
    env = TransformedEnv(ToyContextEnv(num_envs=1), StateActionHistory(2))
    td = env.reset()
    # s = [position, step/10]; width (L+1)*2 + L*1 = 8
    assert td["observation"].tolist() == [[0, 0, 0, 0, 0, 0, 0, 0]]
    td = env.step(td.set("action", torch.tensor([1])))
    assert torch.allclose(td["next", "observation"], torch.tensor([[0, 0, 0, 0, 0, 1, 1, 0.1]]))  # [s0,0,s0,a0,s1]
    td = env.step(step_mdp(td).set("action", torch.tensor([0])))
    assert torch.allclose(td["next", "observation"], torch.tensor([[0, 0, 1, 1, 0.1, 0, 0, 0.2]]))  # [s0,a0,s1,a1,s2]
    td = env.step(step_mdp(td).set("action", torch.tensor([0])))
    assert torch.allclose(td["next", "observation"], torch.tensor([[1, 0.1, 0, 0, 0.2, 0, -1, 0.3]]))


def test_step_by_step_against_reference_through_partial_resets():
    """Manual loop: random actions, auto-resets when done plus forced resets of chosen sub-envs."""
    n, steps = 3, 16
    env = TransformedEnv(ToyContextEnv(num_envs=n), StateActionHistory(2, out_key="history"))
    policy = ScriptedPolicy((n,), steps, seed=3)
    forced = {4: [True, False, False], 9: [False, True, True], 10: [True, False, False]}
    td = env.reset()
    states, actions = [[td["observation"][i]] for i in range(n)], [[] for _ in range(n)]
    partial_seen = 0
    for t in range(steps):
        td = policy(td)
        td = env.step(td)
        for i in range(n):
            actions[i].append(td["action"][i].float().reshape(1))
            states[i].append(td["next", "observation"][i])
            if len(actions[i]) >= 2:  # [s_{t-1}, a_{t-1}, s_t, a_t, s_{t+1}]
                parts = [states[i][-3], actions[i][-2], states[i][-2], actions[i][-1], states[i][-1]]
            else:  # first step of the episode: [s0, 0, s0, a0, s1]
                parts = [states[i][0], torch.zeros(1), states[i][0], actions[i][0], states[i][1]]
            expected = torch.cat(parts)
            assert torch.equal(td["next", "history"][i], expected), (t, i)
        td = step_mdp(td)
        reset = td["done"].squeeze(-1).clone()
        if t in forced:
            reset |= torch.tensor(forced[t])
        if reset.any():
            partial_seen += int(not reset.all())
            before = td["history"].clone()
            td = env.reset(td.set("_reset", reset.unsqueeze(-1)))
            for i in range(n):
                if reset[i]:
                    s0 = td["observation"][i]
                    assert torch.equal(td["history"][i], torch.cat([s0, torch.zeros(1), s0, torch.zeros(1), s0]))
                    states[i], actions[i] = [s0], []
                else:
                    assert torch.equal(td["history"][i], before[i])
    assert partial_seen >= 3


@pytest.mark.parametrize("length", [0, 1, 2, 4])
def test_rollout_matches_reference_any_length(length):
    n, steps = 4, 20
    env = TransformedEnv(ToyContextEnv(num_envs=n), StateActionHistory(length, out_key="history"))
    td = env.rollout(steps, ScriptedPolicy((n,), steps, seed=length), break_when_any_done=False)
    starts = episode_starts(td)
    assert starts[:, 1:].sum() >= 4  # several auto-resets, at different times
    root, nxt = history_reference(td["observation"], td["next", "observation"], td["action"].float().unsqueeze(-1),
                                  starts, length)
    assert td["history"].shape[-1] == (length + 1) * 2 + length
    torch.testing.assert_close(td["history"], root, rtol=0, atol=0)
    torch.testing.assert_close(td["next", "history"], nxt, rtol=0, atol=0)
    if length == 0:
        assert torch.equal(td["history"], td["observation"])


def test_in_place_default_replaces_observation_and_spec():
    env = TransformedEnv(ToyContextEnv(num_envs=2), StateActionHistory(2))
    assert env.observation_spec["observation"].shape == (2, 8)
    assert isinstance(env.observation_spec["observation"], Unbounded)
    check_env_specs(env)
    assert env.rollout(3)["next", "observation"].shape == (2, 3, 8)


def test_one_hot_discrete_actions():
    env = TransformedEnv(ToyContextEnv(num_envs=1), StateActionHistory(2, discrete_action="one_hot"))
    assert env.observation_spec["observation"].shape == (1, 10)
    td = env.step(env.reset().set("action", torch.tensor([1])))
    # [s0, 0 0, s0, onehot(1), s1]
    assert torch.allclose(td["next", "observation"], torch.tensor([[0, 0, 0, 0, 0, 0, 0, 1, 1, 0.1]]))
    check_env_specs(env)


@pytest.mark.parametrize("mode, width, first_action", [("index", 7 * 3 + 2, [3.0]), ("one_hot", 7 * 3 + 14, None)])
def test_onehot_action_spec(mode, width, first_action):
    env = TransformedEnv(DiscreteActionVecMockEnv(), StateActionHistory(2, discrete_action=mode))
    assert env.observation_spec["observation"].shape == (width,)
    check_env_specs(env)
    td = env.reset()
    action = torch.zeros(7, dtype=torch.long)
    action[3] = 1
    td = env.step(td.set("action", action))
    w = 1 if mode == "index" else 7
    a0 = td["next", "observation"][7 + w + 7 : 7 + w + 7 + w]  # [s0, pad, s0, a0, s1]
    assert a0.tolist() == (first_action if first_action is not None else action.float().tolist())


def test_continuous_actions_values_and_bounded_spec():
    env = TransformedEnv(ToyContinuousEnv(num_envs=2), StateActionHistory(2, out_key="history"))
    spec = env.observation_spec["history"]
    assert isinstance(spec, Bounded) and spec.shape == (2, 3 * 3 + 2 * 2)
    s_lo, s_hi, a_lo, a_hi = [-5, -5, 0], [5, 5, 1], [-1, -1], [1, 1]
    assert spec.space.low[0].tolist() == s_lo + a_lo + s_lo + a_lo + s_lo
    assert spec.space.high[0].tolist() == s_hi + a_hi + s_hi + a_hi + s_hi
    check_env_specs(env)
    steps = 12
    td = env.rollout(steps, ScriptedPolicy((2,), steps, continuous_dim=2, seed=1), break_when_any_done=False)
    root, nxt = history_reference(td["observation"], td["next", "observation"], td["action"], episode_starts(td), 2)
    torch.testing.assert_close(td["history"], root, rtol=0, atol=0)
    torch.testing.assert_close(td["next", "history"], nxt, rtol=0, atol=0)
    assert spec.is_in(td["next", "history"][:, -1])


def test_zero_action_padding_widens_action_bounds():
    from torchrl.testing.mocking_classes import ContinuousActionVecMockEnv

    env = TransformedEnv(ContinuousActionVecMockEnv(), StateActionHistory(1))
    assert env.observation_spec["observation"].shape == (7 * 2 + 7,)
    check_env_specs(env)


def test_offline_forward_rebuilds_the_online_history():
    n, steps = 3, 18
    env = TransformedEnv(ToyContextEnv(num_envs=n), StateActionHistory(2, out_key="history"))
    td = env.rollout(steps, ScriptedPolicy((n,), steps, seed=7), break_when_any_done=False)
    offline = StateActionHistory(2, out_key="rebuilt")(td.exclude("history", ("next", "history")))
    torch.testing.assert_close(offline["rebuilt"], td["history"], rtol=0, atol=0)
    torch.testing.assert_close(offline["next", "rebuilt"], td["next", "history"], rtol=0, atol=0)


@pytest.mark.parametrize("length", [-1, 1.5, True, "2"])
def test_bad_length_raises(length):
    with pytest.raises(ValueError, match=f"history length must be an integer >= 0, got {length!r}"):
        StateActionHistory(length)


def test_bad_discrete_mode_and_non_flat_observation():
    with pytest.raises(ValueError, match="discrete_action must be one of"):
        StateActionHistory(2, discrete_action="onehot")
    env = DiscreteActionConvMockEnv()  # "pixels" [1, 7, 7]
    with pytest.raises(ValueError, match=r"event shape \(1, 7, 7\)"):
        TransformedEnv(env, StateActionHistory(2, in_key="pixels")).observation_spec


def test_step_before_reset_raises():
    env = TransformedEnv(ToyContextEnv(num_envs=1), StateActionHistory(2))
    td = TensorDict({"action": torch.tensor([1]), "context": torch.tensor([[1.0, 0.0]])}, batch_size=[1])
    with pytest.raises(RuntimeError, match="stepped before it was reset"):
        env.step(td)


@pytest.mark.parametrize(
    "env_id, simulator, width",
    [
        ("MOLunarLanderDR-v0", "Box2D", 26),  # SPEC: obs 8, Discrete(4) as an index -> 3*8 + 2*1
        ("MOLunarLanderContinuousDR-v0", "Box2D", 28),
        ("MOHopperDR-v5", "mujoco", 39),
        ("MOHalfCheetahDR-v5", "mujoco", 63),
        ("MOHumanoidDR-v5", "mujoco", 1078),
    ],
)
def test_paper_history_widths_on_the_real_domains(env_id, simulator, width):
    pytest.importorskip(simulator)
    from morl_trl.envs import make_env

    env = make_env(env_id, num_envs=2, seed=0)  # (every domain is in the package: only the simulator may be missing)
    env = env.append_transform(StateActionHistory(2))
    assert env.observation_spec["observation"].shape == (2, width)
    td = env.rollout(3, break_when_any_done=False)
    assert td["next", "observation"].shape == (2, 3, width)
    d = env.base_env.observation_spec["observation"].shape[-1]
    a = (width - 3 * d) // 2
    reset, step1 = td["observation"][:, 0], td["next", "observation"][:, 0]
    s0 = reset[:, -d:]
    assert torch.equal(reset, torch.cat([s0, torch.zeros(2, a), s0, torch.zeros(2, a), s0], -1))
    a0 = td["action"][:, 0].reshape(2, -1).float()
    assert torch.equal(step1[:, : 2 * d + 2 * a], torch.cat([s0, torch.zeros(2, a), s0, a0], -1))
