"""Hard target copies at exactly the configured period (issue 48).

TorchRL's ``HardUpdate(n)`` copies every ``n + 1`` calls: GPI's recipe, which calls its updater once per
``target_update_period`` frames with ``n = 1``, copied every second time (a target period of 2,000
frames where MORL-Baselines' ``global_step % target_net_update_freq == 0`` gives 1,000), and Envelope's
``n = 200`` copied every 201 updates.
"""

import torch

from morl_trl.objectives import EnvelopeQLoss, GPILoss, GPIQNetwork, make_vector_q_network
from morl_trl.objectives.updaters import PeriodicHardUpdate
from morl_trl.recipes import resolve_config
from morl_trl.training.agent import target_updater
from morl_trl.algorithms.gpi.recipe import make_gpi_agent
from morl_trl.recipes.off_policy import make_training_env


def _copies(loss, updater, calls: int) -> list[int]:
    """The calls (1-based) after which the target equals the online parameters, each call preceded by a change."""
    out = []
    for call in range(1, calls + 1):
        with torch.no_grad():
            for p in loss.value_network_params.values(True, True):
                p.add_(1.0)
        updater.step()
        if all(torch.equal(a, b) for a, b in zip(loss.value_network_params.values(True, True),
                                                 loss.target_value_network_params.values(True, True))):
            out.append(call)
    return out


def test_a_periodic_hard_update_copies_every_period_calls():
    loss = GPILoss(GPIQNetwork(2, 4, 2, hidden=(8, 8)))
    assert _copies(loss, PeriodicHardUpdate(loss, value_network_update_interval=1), 3) == [1, 2, 3]
    loss = GPILoss(GPIQNetwork(2, 4, 2, hidden=(8, 8)))
    assert _copies(loss, PeriodicHardUpdate(loss, value_network_update_interval=3), 9) == [3, 6, 9]


def test_gpis_agent_copies_its_target_at_every_call():
    """The recipe calls the updater once per target_update_period frames (MB: global_step % 1000 == 0)."""
    torch.manual_seed(0)
    cfg = resolve_config("gpi_ls", "deep-sea-treasure-v0", hidden=(8, 8), progress=False)
    env = make_training_env(cfg, torch.device("cpu"))
    agent = make_gpi_agent(cfg, env, gamma=0.99, device=torch.device("cpu"))
    assert _copies(agent.loss, agent.target_updater, 4) == [1, 2, 3, 4]


def test_envelopes_target_is_copied_every_target_update_period_updates():
    cfg = resolve_config("envelope", "deep-sea-treasure-v0", target_update_period=5, tau=None)
    loss = EnvelopeQLoss(make_vector_q_network(2, 4, 2, num_cells=(8,)), num_preference_samples=2)
    assert _copies(loss, target_updater(cfg, loss), 10) == [5, 10]
