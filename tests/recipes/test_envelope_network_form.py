"""Envelope's Q-network form on a foreign env: MORL-Baselines 1.3.0's QNet (issue 48).

The authors' form (``w`` concatenated after the first hidden layer) stays the paper domains' default.
At MB's defaults on deep-sea-treasure-v0 (seed 11, 3,000 frames) it diverged (batch-mean w.Q above 40,
past the largest discounted return, ~20; HV ratio 0.047), where MB's own form (``w`` at the input,
``layer_init``'s orthogonal weights) reached 0.49 with Q estimates as MB's own run's (about 20-27 by
2,750 updates); MB's form still diverged on seed 14, so it is the parity setting, not a full cure.
"""

import pytest
import torch

pytest.importorskip("mo_gymnasium")

from morl_trl.recipes import build_agent, build_training_env, resolve_config  # noqa: E402


def _linears(agent):
    return [m for m in agent.loss.value_network.module.modules() if isinstance(m, torch.nn.Linear)]


def _net(env_id, **kw):
    cfg = resolve_config("envelope", env_id, hidden=(16, 16), **kw)
    env = build_training_env(cfg, torch.device("cpu"))
    return cfg, build_agent(cfg, env, gamma=0.99, device=torch.device("cpu"))


def test_a_foreign_env_gets_morl_baselines_qnet():
    cfg, agent = _net("deep-sea-treasure-v0")
    assert cfg.envelope_network == "mb"
    net = agent.loss.value_network.module
    assert net.trunk is None  # w at the input: MB's mlp(obs_dim + k, action_dim * k, net_arch)
    layers = _linears(agent)
    assert layers[0].in_features == 2 + 2  # DST: (row, col) and 2 objectives
    for lin in layers:  # layer_init: orthogonal weights with gain 1, zero biases
        w = lin.weight.detach()
        gram = w @ w.T if w.shape[0] <= w.shape[1] else w.T @ w
        assert torch.allclose(gram, torch.eye(gram.shape[0]), atol=1e-5)
        assert torch.count_nonzero(lin.bias) == 0


def test_the_paper_domains_keep_the_authors_form_and_input_keeps_pytorchs_init():
    cfg, agent = _net("MOLavaGridDR-v0")
    assert cfg.envelope_network == "authors" and agent.loss.value_network.module.trunk is not None
    _, agent = _net("deep-sea-treasure-v0", envelope_network="input")
    first = _linears(agent)[0]
    assert agent.loss.value_network.module.trunk is None and torch.count_nonzero(first.bias) > 0
