"""What ``benchmarks/gpu/check.sh`` runs first (``pytest -m gpu``): every learner and the trainer's
loop on each device, and the captured update against the eager one.

Every test is parametrized by device: ``cpu`` always, ``cuda`` when a CUDA device is present, so
the CPU run of the suite exercises the same code the GPU check runs. On the CPU, the CPU
variants of the learners already covered by their own tests are marked ``slow``.
"""

from __future__ import annotations

import warnings

import pytest
import torch

from morl_trl.envs import domain_of
from morl_trl.recipes import build_agent, build_training_env, resolve_config
from morl_trl.algorithms.registry import algorithm

from morl_trl.training.parts import make_collector, make_replay_buffer, run_discount
from tests.recipes.test_capture import capture, params_of, setup, update

pytestmark = [pytest.mark.gpu, pytest.mark.filterwarnings("ignore")]

CUDA = torch.cuda.is_available()
DEVICES = ["cpu", "cuda"] if CUDA else ["cpu"]

# algo -> (env id, overrides on top of --quick): tiny networks, learning from the first batch
TINY = dict(hidden=(16, 16), batch_size=16, init_random_frames=0, buffer_size=2_048)
LEARNERS = {
    "envelope": ("MOLavaGridDR-v0", {}),
    "capql": ("MOHopperDR-v5", {}),
    "mosac_discrete": ("MOLavaGridDR-v0", {}),
    "sac": ("MOHopperDR-v5", {}),
    "gpi_ls": ("MOLavaGridDR-v0", {}),
    "gpi_pd": ("MOLavaGridDR-v0", {}),
    "morld": ("MOHopperDR-v5", {}),
    "pcn": ("MOLavaGridDR-v0", dict(num_envs=2, frames_per_batch=512, pcn_er_episodes=1, pcn_step_episodes=1,
                                    pcn_model_updates=2)),
    "pgmorl": ("MOHopperDR-v5", dict(num_envs=12, frames_per_batch=12 * 16, pgmorl_pop=6, pgmorl_envs_per_member=2,
                                     pgmorl_epochs=1, pgmorl_minibatches=2)),
}
# PCN and PGMORL have no off-policy replay buffer (and PGMORL no batch_size): their configs refuse those keys
NOT_KEYS = {"pcn": ("buffer_size", "init_random_frames"), "pgmorl": ("batch_size", "buffer_size", "init_random_frames")}
# the CPU variants that run in the default suite (the rest are covered on the CPU by their own tests)
CPU_DEFAULT = ("envelope", "capql")


def _cases():
    for device in DEVICES:
        for algo in LEARNERS:
            marks = [pytest.mark.slow] if device == "cpu" and algo not in CPU_DEFAULT else []
            yield pytest.param(device, algo, marks=marks, id=f"{device}-{algo}")


def _needs(env_id):
    if "Hopper" in env_id:
        pytest.importorskip("mujoco")


def _leaves(agent):
    return {k: v.detach().clone() for k, v in agent.loss.state_dict().items() if torch.is_tensor(v) and v.is_floating_point()}


@pytest.mark.parametrize("device, algo", list(_cases()))
def test_every_learner_trains_on_the_device(device, algo):
    """The trainer's loop (collector -> learn -> schedules -> policy sync) on ``device``: updates
    happen, every loss is finite, the networks move and stay on ``device``."""
    env_id, extra = LEARNERS[algo]
    _needs(env_id)
    dev = torch.device(device)
    cfg = resolve_config(algo, env_id, quick=True, device=device, logger="none", progress=False,
                         **{**{k: v for k, v in TINY.items() if k not in NOT_KEYS.get(algo, ())}, **extra})
    torch.manual_seed(0)
    env = build_training_env(cfg, dev)
    agent = build_agent(cfg, env, gamma=run_discount(cfg, domain_of(env_id)), device=dev)
    buffer = make_replay_buffer(cfg, dev)
    start = _leaves(agent)
    collector = make_collector(cfg, env, agent.explore_policy, dev)
    frames, updates, losses = 0, 0, None
    try:
        for i, batch in enumerate(collector):
            assert batch.device is None or batch.device.type == dev.type
            frames += batch.numel()
            out, n = algorithm(algo).on_batch(agent, batch, buffer, frames)  # the recipe's own step
            collector.update_policy_weights_()
            updates += n
            losses = out if out is not None else losses
            if updates and i >= 1:
                break
            assert i < 40, f"{algo}: no update after {frames} frames"
    finally:
        collector.shutdown()
    assert updates > 0 and losses is not None
    finite = {k: bool(torch.isfinite(v).all()) for k, v in losses.items(True, True)
              if isinstance(k, str) and k.startswith("loss")}
    assert finite and all(finite.values()), finite
    end = _leaves(agent)
    moved = [k for k in start if not torch.equal(start[k].cpu(), end[k].cpu())]
    assert moved, f"{algo}: no parameter moved in {updates} updates"
    assert {v.device.type for v in end.values()} == {dev.type}


def _capture_modes():
    for device in DEVICES:
        modes = ["step"] + (["cudagraphs", "both"] if device == "cuda" else [])
        for name in ("envelope", "capql"):
            for mode in modes:
                marks = [pytest.mark.slow] if mode == "both" else []  # a compile: minutes (not in the GPU check)
                yield pytest.param(device, name, mode, marks=marks, id=f"{device}-{name}-{mode}")


@pytest.mark.parametrize("device, name, mode", list(_capture_modes()))
def test_captured_update_equals_the_eager_update(device, name, mode):
    """From the same state and the same random stream (reseeded before each update), the
    captured update (``step``: the capturable function run as is; ``cudagraphs``: replayed CUDA
    graphs; ``both``: compiled, then graphed) gives the eager update's parameters.

    Eight updates: past the CUDA graph's warm-up calls and its capture, so replays are compared."""
    if "Hopper" in setup.__globals__["CASES"][name][1]:
        pytest.importorskip("mujoco")
    dev = torch.device(device)
    overrides = {"step": {}, "cudagraphs": dict(cudagraphs=True), "both": dict(cudagraphs=True, compile=True)}[mode]
    _, eager, buf_e = setup(name, device=dev)
    _, captured, buf_c = setup(name, device=dev, finite_check_interval=4, **overrides)
    captured.loss.load_state_dict(eager.loss.state_dict())
    if mode == "step":
        capture(captured)  # the captured path, run eagerly
    start = params_of(eager)
    with torch._inductor.config.patch(fallback_random=True), warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for i in range(8):
            for agent, buffer in ((eager, buf_e), (captured, buf_c)):
                torch.manual_seed(100 + i)
                update(agent, buffer)
    if device == "cuda":
        torch.cuda.synchronize()
    # same kernels: float rounding only; compiled kernels fuse differently (Adam's first steps
    # turn tiny gradient differences into up to lr-sized ones)
    tol = dict(rtol=1e-5, atol=1e-6) if mode in ("step", "cudagraphs") else dict(rtol=1e-3, atol=1e-3)
    end_e, end_c = params_of(eager), params_of(captured)
    for key in end_e:
        torch.testing.assert_close(end_c[key], end_e[key], msg=key, **tol)
    assert any(not torch.equal(start[k], end_e[k]) for k in start if "target" not in k)


def _whole_modes():
    for device in DEVICES:
        for mode in ["step"] + (["cudagraphs", "both"] if device == "cuda" else []):
            marks = [pytest.mark.slow] if mode == "both" else []
            yield pytest.param(device, mode, marks=marks, id=f"{device}-{mode}")


@pytest.mark.parametrize("device, mode", list(_whole_modes()))
def test_the_whole_envelope_update_in_one_graph_equals_the_eager_update(device, mode):
    """``capture_sampling``: sampling from the sum tree, the update and the priority writes as
    one host-free function (on CUDA one graph) give the eager update's parameters, priorities
    and largest priority, from the same state and random stream."""
    dev = torch.device(device)
    overrides = {"step": {}, "cudagraphs": dict(cudagraphs=True), "both": dict(cudagraphs=True, compile=True)}[mode]
    _, eager, buf_e = setup("envelope", device=dev)
    _, whole, buf_w = setup("envelope", device=dev, finite_check_interval=4, **overrides)
    whole.cfg.capture_sampling = True
    whole.loss.load_state_dict(eager.loss.state_dict())
    if mode == "step":
        capture(whole)  # the host-free function, run eagerly
    start = params_of(eager)
    with torch._inductor.config.patch(fallback_random=True), warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for i in range(8):
            for agent, buffer in ((eager, buf_e), (whole, buf_w)):
                torch.manual_seed(200 + i)
                update(agent, buffer)
    assert whole.captured._whole is not None  # the whole-update path ran
    assert (whole.captured._graph is not None) == (mode != "step")
    tol = dict(rtol=1e-5, atol=1e-6) if mode != "both" else dict(rtol=1e-3, atol=1e-3)
    end_e, end_w = params_of(eager), params_of(whole)
    for key in end_e:
        torch.testing.assert_close(end_w[key], end_e[key], msg=key, **tol)
    assert any(not torch.equal(start[k], end_e[k]) for k in start if "target" not in k)
    se, sw = buf_e._sampler, buf_w._sampler
    torch.testing.assert_close(sw._sum_tree._tree, se._sum_tree._tree, **tol)
    torch.testing.assert_close(sw._min_tree._tree, se._min_tree._tree, **tol)
    torch.testing.assert_close(torch.as_tensor(sw._max_priority[0]).cpu(), torch.as_tensor(se._max_priority[0]).cpu(), **tol)
    assert not torch.equal(se._sum_tree.leaves().cpu(), torch.full_like(se._sum_tree.leaves().cpu(), 1.0))


def test_assign_unchecked_keeps_the_last_write_of_a_repeated_index_like_setitem():
    from morl_trl.data.segment_tree import MinSegmentTree, SumSegmentTree

    for cls in (SumSegmentTree, MinSegmentTree):
        a, b = cls(10), cls(10)
        a[torch.arange(10)] = torch.arange(1.0, 11.0)
        b[torch.arange(10)] = torch.arange(1.0, 11.0)
        index = torch.tensor([3, 7, 3, 0, 7, 3])
        value = torch.tensor([0.5, 2.0, 4.0, 8.0, 16.0, 32.0])
        a[index] = value
        b.assign_unchecked(index, value)
        assert torch.equal(a._tree, b._tree)
        assert float(b.query(0, 10)) == (55.0 - 1 - 4 - 8 + 8 + 32 + 16 if cls is SumSegmentTree else 2.0)


@pytest.mark.slow  # dynamo traces the whole update: a minute or more on a CPU core
@pytest.mark.parametrize("name", ["envelope", "capql"])
def test_the_captured_functions_read_no_device_value(name):
    """``torch._dynamo.explain`` over the captured function (Envelope: the whole update, sampling
    and priority writes included; CAPQL: the step): no graph break with a reason, i.e. no
    ``.item()``, ``bool(tensor)``, ``.cpu()`` or data-dependent branch -- nothing that would make
    the host wait for the device. (The breaks dynamo always makes at ``backward()`` and the
    optimizer step carry no reason.)"""
    _, agent, buffer = setup(name)
    agent.cfg.capture_sampling = True
    captured = capture(agent)
    if name == "envelope":
        assert captured._samples_in_graph(buffer)
        fn, args = captured._build_whole(buffer), ()
    else:
        assert not captured._samples_in_graph(buffer)  # uniform replay: the step alone is captured
        fn, args = captured.step, (buffer.sample().to(agent.device),)
    torch._dynamo.reset()
    explained = torch._dynamo.explain(fn)(*args)
    assert explained.graph_count >= 1 and explained.op_count > 20
    assert [r.reason.splitlines()[0] for r in explained.break_reasons] == []
