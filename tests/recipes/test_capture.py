"""The captured update (compile / CUDA graphs) against the eager one, and its on-device guard."""

import copy

import pytest
import torch

from morl_trl.recipes import build_agent, build_training_env, resolve_config
from morl_trl.algorithms.actor_critic import recipe as actor_critic
from morl_trl.algorithms.envelope import recipe as envelope
from morl_trl.training.agent import NonFiniteLossError, adam, obs_shape, runs_captured
from morl_trl.training.capture import CapturedUpdate
from morl_trl.recipes.off_policy import make_replay_buffer
from tests.objectives._helpers import random_batch

pytestmark = pytest.mark.filterwarnings("ignore:No target network updater")

CPU = torch.device("cpu")
CASES = {  # (algo, env id, discrete): Polyak targets + plain buffer / hard targets + PER + clipping
    "capql": ("capql", "MOHopperDR-v5", False),
    "envelope": ("envelope", "MOLavaGridDR-v0", True),
    "mosac": ("mosac", "MOHopperDR-v5", False),  # the delayed actor (policy_freq 2): two captured updates
}
RECIPE = {"capql": actor_critic, "envelope": envelope, "mosac": actor_critic}  # (their update, gradient_step)


def loss_keys(agent) -> list:
    return [k for k in agent.loss.out_keys if k.startswith("loss_")]


def update(agent, buffer):
    """The recipe's update (the one ``morl-trl train`` runs)."""
    return RECIPE[agent.cfg.algo].update(agent, buffer)


def capture(agent) -> CapturedUpdate:
    """The recipe's gradient step, wrapped as a captured update would be (built uncompiled if ``compile`` is off)."""
    agent.captured = CapturedUpdate(agent, RECIPE[agent.cfg.algo].gradient_step)
    return agent.captured


def setup(name, device=CPU, n=256, **overrides):
    algo, env_id, discrete = CASES[name]
    cfg = resolve_config(algo, env_id, quick=True, hidden=(32, 32), batch_size=16, buffer_size=1024,
                         device=str(device), **overrides)
    torch.manual_seed(0)
    env = build_training_env(cfg, device)
    agent = build_agent(cfg, env, gamma=0.99, device=device)
    k = agent.loss.num_objectives
    (obs,) = obs_shape(env)
    if discrete:
        data = random_batch(n, obs, k, num_actions=int(env.full_action_spec[env.action_key].space.n))
    else:
        data = random_batch(n, obs, k, action_dim=env.full_action_spec[env.action_key].shape[-1])
    buffer = make_replay_buffer(cfg, device)
    buffer.extend(data.to(device))
    return cfg, agent, buffer


def params_of(agent):
    return {k: v.detach().clone() for k, v in agent.loss.state_dict().items()}


def run(agent, buffer, updates, seed=1):
    torch.manual_seed(seed)
    losses = [update(agent, buffer) for _ in range(updates)]
    return losses, params_of(agent)


def same_start(name, **overrides):
    """Two agents and buffers from the same state: eager, and one with ``overrides`` (the captured one)."""
    cfg, eager, buf_e = setup(name)
    _, captured, buf_c = setup(name, **overrides)
    captured.loss.load_state_dict(eager.loss.state_dict())
    return eager, buf_e, captured, buf_c


@pytest.mark.parametrize("name", list(CASES))
def test_captured_step_without_compile_matches_the_eager_update(name):
    eager, buf_e, captured, buf_c = same_start(name)
    capture(captured)  # the captured path, run eagerly
    start = params_of(eager)
    out_e, params_e = run(eager, buf_e, 4)
    out_c, params_c = run(captured, buf_c, 4)
    for a, b in zip(out_e, out_c):
        for key in loss_keys(eager):
            torch.testing.assert_close(a[key], b[key], rtol=1e-6, atol=1e-7, equal_nan=True)  # (NaN: no actor turn yet)
    for key in params_e:
        torch.testing.assert_close(params_e[key], params_c[key], rtol=1e-6, atol=1e-7, msg=key)
    moved = [k for k in start if not torch.equal(start[k], params_e[k])]
    assert any("target" in k for k in moved) == (name != "envelope")  # Polyak moves targets; a hard copy waits
    assert any("target" not in k and k.endswith("weight") for k in moved)


@pytest.mark.parametrize("name", list(CASES))
def test_a_non_finite_update_is_skipped_on_the_device_and_reported(name):
    _, agent, buffer = setup(name, compile=True, finite_check_interval=3)
    agent.cfg.compile = False  # build it uncompiled: the guard's logic, without the compile time
    captured = capture(agent)
    update(agent, buffer)  # one good update
    before = params_of(agent)
    steps = {n: [s["step"].clone() for s in o.state.values()] for n, o in agent.optimizers.items()}
    poisoned = buffer.sample()
    poisoned["next", "reward"][0, 0] = float("nan")
    result = captured.step(poisoned)  # the poisoned update: nothing moves
    assert not torch.isfinite(sum(result[k] for k in loss_keys(agent)))
    after = params_of(agent)
    for key in before:
        assert torch.equal(before[key], after[key]), key
    for n, o in agent.optimizers.items():
        assert [s["step"] for s in o.state.values()] == steps[n]
    assert torch.isfinite(result["_priority"]).all()
    assert captured.skipped.item() == 1.0
    captured.since_check += 1  # the poisoned step, called directly
    with pytest.raises(NonFiniteLossError, match="1 of the last 3 updates had a non-finite loss"):
        update(agent, buffer)  # the third update since the check reads the flag
    assert captured.skipped.item() == 0.0


def test_captured_update_needs_fused_optimizers_and_cuda_for_graphs():
    _, agent, _ = setup("capql", compile=True)
    agent.optimizers["actor"] = torch.optim.Adam(agent.loss.actor_network_params.values(True, True), lr=1e-3)
    with pytest.raises(ValueError, match=r"needs fused optimizers.*\['actor'\]"):
        capture(agent)
    with pytest.raises(ValueError, match="'cudagraphs' .* is true but device is 'cpu'"):
        resolve_config("capql", "MOHopperDR-v5", cudagraphs=True)
    _, agent, _ = setup("capql")
    agent.cfg.cudagraphs = True  # past the config's check
    with pytest.raises(ValueError, match="cudagraphs=true needs device='cuda'"):
        capture(agent)


def test_adam_is_fused_and_matches_the_per_tensor_loop():
    torch.manual_seed(0)
    params = [torch.nn.Parameter(torch.randn(8, 4)), torch.nn.Parameter(torch.randn(4))]
    twin = [torch.nn.Parameter(p.detach().clone()) for p in params]
    fused, loop = adam(params, 1e-2), torch.optim.Adam(twin, lr=1e-2, foreach=False)
    assert fused.defaults["fused"] and not loop.defaults["fused"]
    for i in range(5):
        for ps, opt in ((params, fused), (twin, loop)):
            torch.manual_seed(i)
            opt.zero_grad()
            sum((p * torch.randn_like(p)).sum() for p in ps).backward()
            opt.step()
    for a, b in zip(params, twin):
        torch.testing.assert_close(a, b, rtol=1e-6, atol=1e-7)
    assert not torch.equal(params[0], twin[0] * 0)


@pytest.mark.slow
def test_compiled_update_matches_the_eager_update_on_cpu():
    eager, buf_e, compiled, buf_c = same_start("capql", compile=True, finite_check_interval=2)
    out_e, params_e = run(eager, buf_e, 3)
    out_c, params_c = run(compiled, buf_c, 3)
    assert isinstance(compiled.captured, CapturedUpdate) and compiled.captured.fn is not compiled.captured.step
    assert compiled.captured.gradient_step is actor_critic.gradient_step  # the recipe's own step, compiled
    for a, b in zip(out_e, out_c):
        for key in loss_keys(eager):
            torch.testing.assert_close(a[key], b[key], rtol=1e-5, atol=1e-6)
    for key in params_e:
        torch.testing.assert_close(params_e[key], params_c[key], rtol=1e-5, atol=1e-6, msg=key)


@pytest.mark.skipif(not torch.cuda.is_available(), reason="CUDA graphs need a CUDA device (none here)")
@pytest.mark.parametrize("name", list(CASES))
def test_cuda_graphed_update_learns_and_skips_non_finite_updates_on_cuda(name):
    """Graph replays draw other random numbers than eager calls, so this checks behaviour, not equality."""
    cuda = torch.device("cuda")
    _, agent, buffer = setup(name, device=cuda, cudagraphs=True, finite_check_interval=1000)
    start = params_of(agent)
    losses = [update(agent, buffer) for _ in range(8)]  # warm-up calls, the capture, then replays
    assert all(torch.isfinite(out[k]).all() for out in losses for k in loss_keys(agent))
    moved = [k for k, v in params_of(agent).items() if not torch.equal(v, start[k])]
    assert any(k.endswith("weight") and "target" not in k for k in moved)
    captured = agent.captured
    before = params_of(agent)
    poisoned = buffer.sample()
    poisoned["next", "reward"][0, 0] = float("nan")
    captured.fn(poisoned)  # the graph, replayed on a non-finite batch
    for key, value in params_of(agent).items():
        assert torch.equal(value, before[key]), key
    assert captured.skipped.item() == 1.0


def test_a_checkpoint_of_a_per_tensor_adam_keeps_the_agent_fused():
    _, agent, buffer = setup("capql")
    update(agent, buffer)
    state = agent.state_dict()
    for opt_state in state["optimizers"].values():  # as a checkpoint from before the fused optimizers
        for group in opt_state["param_groups"]:
            group["fused"] = None
    _, other, _ = setup("capql")
    other.load_state_dict(state)
    for opt in other.optimizers.values():
        assert all(group["fused"] is True for group in opt.param_groups)
        assert all(st["step"].item() == 1.0 for st in opt.state.values())
    update(other, buffer)  # steps with the fused kernel
    assert all(st["step"].item() == 2.0 for opt in other.optimizers.values() for st in opt.state.values())


def test_the_device_guard_is_used_on_accelerators_and_with_capture_only():
    _, agent, _ = setup("capql")
    assert runs_captured(agent) is False  # the CPU checks on the host, at once
    _, agent, _ = setup("capql")
    agent.device = torch.device("cuda")  # (not run: the decision only)
    assert runs_captured(agent) is True
    _, agent, _ = setup("capql")
    agent.device = torch.device("cuda")
    agent.optimizers["actor"] = torch.optim.Adam(agent.loss.actor_network_params.values(True, True), lr=1e-3)
    assert runs_captured(agent) is False  # a per-tensor optimizer cannot skip on the device: host check
    _, agent, _ = setup("capql", compile=True)
    assert runs_captured(agent) is True


@pytest.mark.parametrize("algo, env_id", [("gpi_ls", "MOLavaGridDR-v0"), ("pcn", "MOLavaGridDR-v0"),
                                          ("morld", "MOHopperDR-v5"), ("pgmorl", "MOHopperDR-v5")])
def test_capture_is_refused_for_agents_with_their_own_update(algo, env_id):
    from morl_trl.recipes import build_agent, build_training_env

    cfg = resolve_config(algo, env_id, hidden=(16,), num_envs=24 if algo == "pgmorl" else 2, compile=True)
    env = build_training_env(cfg, torch.device("cpu"))
    if algo in ("morld", "pgmorl"):
        pytest.importorskip("mujoco")
    with pytest.raises(ValueError, match=rf"compile / cudagraphs capture an update written for it .*; {algo}'s is "
                                         r"not: set compile=false and cudagraphs=false"):
        build_agent(cfg, env, gamma=0.99, device=torch.device("cpu"))
