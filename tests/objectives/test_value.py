import pytest
import torch
from tensordict import TensorDict
from tensordict.nn import TensorDictModule

from morl_trl.objectives import VectorTD0Estimator, vector_td0_return_estimate


def test_return_estimate_broadcasts_the_flag_over_objectives():
    reward = torch.tensor([[1.0, -1.0], [0.5, 2.0]])
    next_value = torch.tensor([[10.0, 20.0], [30.0, 40.0]])
    terminated = torch.tensor([[False], [True]])
    out = vector_td0_return_estimate(0.5, next_value, reward, terminated)
    torch.testing.assert_close(out, torch.tensor([[6.0, 9.0], [0.5, 2.0]]))
    # a flag without its trailing singleton dimension is accepted too
    torch.testing.assert_close(vector_td0_return_estimate(0.5, next_value, reward, terminated[:, 0]), out)


@pytest.mark.parametrize(
    "next_value, terminated, match",
    [
        (torch.zeros(2, 3), torch.zeros(2, 1, dtype=torch.bool), r"next_state_value has shape \(2, 3\).*\(2, 2\)"),
        (torch.zeros(2, 2), torch.zeros(2, 2, dtype=torch.bool), r"terminated has shape \(2, 2\)"),
    ],
)
def test_return_estimate_rejects_mismatched_shapes(next_value, terminated, match):
    with pytest.raises(ValueError, match=match):
        vector_td0_return_estimate(0.9, next_value, torch.zeros(2, 2), terminated)


def transitions():
    return TensorDict(
        {
            "observation": torch.tensor([[1.0], [2.0], [3.0]]),
            ("next", "observation"): torch.tensor([[2.0], [3.0], [4.0]]),
            ("next", "reward"): torch.tensor([[1.0, 0.0], [0.0, 1.0], [2.0, 2.0]]),
            ("next", "done"): torch.tensor([[False], [True], [True]]),
            ("next", "terminated"): torch.tensor([[False], [True], [False]]),  # the last one is truncated
        },
        [3],
    )


def test_estimator_with_a_value_network_writes_vector_targets_and_advantages():
    # V(s) = (s, -s): targets worked out by hand with gamma = 0.5
    value_net = TensorDictModule(lambda s: torch.cat([s, -s], -1), in_keys=["observation"], out_keys=["state_value"])
    est = VectorTD0Estimator(gamma=0.5, value_network=value_net)
    td = est(transitions())
    expected = torch.tensor([[1.0 + 1.0, 0.0 - 1.0], [0.0, 1.0], [2.0 + 2.0, 2.0 - 2.0]])
    torch.testing.assert_close(td["value_target"], expected)
    torch.testing.assert_close(td["advantage"], expected - torch.tensor([[1.0, -1.0], [2.0, -2.0], [3.0, -3.0]]))


def test_estimator_reads_values_from_the_data_and_honours_steps_to_next_obs():
    td = transitions()
    td["state_value"] = torch.zeros(3, 2)
    td["next", "state_value"] = torch.ones(3, 2)
    td["steps_to_next_obs"] = torch.tensor([[2], [1], [3]])
    est = VectorTD0Estimator(gamma=0.5)
    target = est.value_estimate(td)
    torch.testing.assert_close(target, torch.tensor([[1.25, 0.25], [0.0, 1.0], [2.125, 2.125]]))


def test_estimator_set_keys():
    est = VectorTD0Estimator(gamma=0.5)
    est.set_keys(reward="vec_reward", terminated="term", done="dn")
    td = TensorDict(
        {("next", "vec_reward"): torch.ones(2, 3), ("next", "term"): torch.tensor([[True], [False]]), ("next", "dn"): torch.tensor([[True], [False]])},
        [2],
    )
    torch.testing.assert_close(est.value_estimate(td, next_value=torch.full((2, 3), 4.0)), torch.tensor([[1.0] * 3, [3.0] * 3]))
