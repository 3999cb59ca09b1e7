"""Agent states written by the code of 2026-11-26, before the one batched linear
(``tests/fixtures/population_states``, made by ``tests/fixtures/make_population_states.py`` at 94d3353),
load into today's agents with identical parameters, and their optimizer moments follow the
parameters: one more optimizer step from the loaded state gives, parameter by parameter, what the
old code computed (recorded in the fixture; to float32 rounding, as another CPU's sin and Adam kernels
round: the loading itself is checked bit for bit)."""

import importlib.util
from pathlib import Path

import pytest
import torch

from morl_trl.training.state_upgrade import upgrade_loss_state
from morl_trl.runs.plain import load_plain

FIXTURES = Path(__file__).resolve().parents[1] / "fixtures"
_spec = importlib.util.spec_from_file_location("make_population_states", FIXTURES / "make_population_states.py")
maker = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(maker)


def _load(case: str):
    saved = load_plain(FIXTURES / "population_states" / f"{case}.pt")
    _, _, agent = maker.build(case)
    old_loss = dict(saved["agent"]["loss"])
    agent.load_state_dict(saved["agent"])
    return agent, saved, old_loss


def _as_current(agent, old: dict) -> dict:
    """The old tensors under the current names, in the current layout (checked independently below)."""
    return upgrade_loss_state(agent.loss, old)[0]


@pytest.mark.parametrize("case", list(maker.CASES))
def test_old_state_loads_and_steps_as_the_old_code(case):
    agent, saved, old_loss = _load(case)
    stepped = _as_current(agent, saved["stepped"])
    maker.sin_step(agent)
    now = agent.loss.state_dict()
    assert sorted(stepped) == sorted(k for k, v in now.items() if torch.is_tensor(v))
    for key, want in stepped.items():  # (recorded on another CPU: one step of sin and Adam, to a few roundings)
        torch.testing.assert_close(now[key], want, rtol=1e-6, atol=1e-7, msg=key)


def test_morld_layers_are_transposed_and_the_archive_converted():
    agent, saved, old_loss = _load("morld_continuous")
    now = agent.loss.state_dict()
    key = "qvalue_network_params.module.mlp.0.weight"
    assert old_loss[key].shape == (2, 3, 8, 42) and now[key].shape == (2, 3, 42, 8)  # [n, P, out, in] -> [n, P, in, out]
    assert torch.equal(now[key], old_loss[key].transpose(-1, -2))
    bias = "actor_network_params.module.0.module.net.mlp.2.bias"
    assert torch.equal(now[bias], old_loss[bias].unsqueeze(-2))
    people = agent.archive.individuals
    assert len(people) == 2
    snap = people[0]["actor"]
    assert snap["module", "0", "module", "net", "mlp", "0", "weight"].shape == (39, 8)  # one member: [in, out]
    assert snap["module", "0", "module", "net", "mlp", "0", "bias"].shape == (1, 8)
    raw = load_plain(FIXTURES / "population_states" / "morld_continuous.pt")["agent"]["morld"]["archive"]
    old_snap = raw["individuals"][0]["actor"]
    assert torch.equal(snap["module", "0", "module", "net", "mlp", "0", "weight"],
                       old_snap["module", "0", "module", "net", "mlp", "0", "weight"].T)
    assert agent.snapshots()[1]["module", "0", "module", "net", "mlp", "2", "weight"].shape == (2, 8, 6)


def test_pgmorl_names_and_member_states_are_converted():
    agent, saved, old_loss = _load("pgmorl")
    now = agent.loss.state_dict()
    assert torch.equal(now["critic_network_params.module.mlp.2.weight"], old_loss["critic_network_params.module.weights.1"])
    assert torch.equal(now["actor_network_params.module.0.module.mean.mlp.0.bias"],
                       old_loss["actor_network_params.module.0.module.mean.biases.0"])
    assert agent.archive_members and all(set(m["actor"]) == set(agent.head.member_state(0))
                                         for m in agent.archive_members)
    individuals = agent.population.individuals
    assert individuals
    agent.head.load_member_state(1, individuals[0]["actor"])  # what the task selection does
    agent.critic.module.load_member_state(1, individuals[0]["critic"])
    assert torch.equal(agent.head.member_state(1)["mean.mlp.0.weight"], individuals[0]["actor"]["mean.mlp.0.weight"])


def test_a_current_state_is_left_as_it_is():
    agent, _, _ = _load("morld")
    state = agent.state_dict()
    loss = dict(state["loss"])
    agent.load_state_dict(state)
    assert all(state["loss"][k] is v for k, v in loss.items())


def test_an_old_concurrent_morld_state_loads_into_the_round_robin_with_its_adam_count_for_every_member():
    from morl_trl.recipes import build_agent, build_training_env, resolve_config

    saved = load_plain(FIXTURES / "population_states" / "morld_continuous.pt")
    old_agent, _, _ = _load("morld_continuous")  # (the concurrent agent it was written by)
    algo, env_id, extra = maker.CASES["morld_continuous"]
    cfg = resolve_config(algo, env_id, progress=False, logger="none", seed=7,
                         **{**extra, "morld_schedule": "round_robin", "updates_per_batch": 0})
    env = build_training_env(cfg, torch.device("cpu"))
    agent = build_agent(cfg, env, gamma=0.99, device=torch.device("cpu"))
    agent.load_state_dict(saved["agent"])
    for key, value in old_agent.loss.state_dict().items():
        assert torch.equal(agent.loss.state_dict()[key], value), key
    # (no round-robin fields in the old state: member 0's turn, nothing counted)
    assert (agent.active, agent.turn_frames, agent.member_updates.tolist(), agent.exchanges) == (0, 0, [0, 0, 0], 2)
    old_step = float(next(iter(old_agent.optimizers["actor"].state.values()))["step"])
    assert old_step > 0 and all(st["step"].tolist() == [old_step] * 3
                                for st in agent.optimizers["actor"].state.values())
    maker.sin_step(agent)  # every member active: the old code's step, to rounding (torch's foreach arithmetic)
    stepped = _as_current(agent, saved["stepped"])
    now = agent.loss.state_dict()
    for key, want in stepped.items():
        torch.testing.assert_close(now[key], want, rtol=1e-6, atol=1e-7)
    with pytest.raises(ValueError, match="morld_schedule='round_robin'"):
        old_agent.load_state_dict(agent.state_dict())
