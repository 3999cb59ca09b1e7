"""MB 1.3.0's Envelope update and ours on one batch with the same weights: targets, loss, gradients, PER priorities.

    PYTHONPATH=. /tmp/mbvenv/bin/python benchmarks/parity/envelope_same_update.py   # MB's venv (issue 48)

MB's QNet (w at the input, layer_init) with a perturbed target copy, its weights copied into our
``envelope_network="mb"`` network; 256 DST-like transitions (10 % terminal), 4 sampled |N(0, I)| weights;
MB's ``update()`` inlined (the batch repeated per w, ``envelope_target``, mse, the priorities of the first w).
Printed on 2026-12-02: targets max |diff| 0.0, loss 54.3345 on both, priorities 1.9e-06, gradients 6.6e-07.
"""
import numpy as np, torch as th, mo_gymnasium as mo_gym
from tensordict import TensorDict
from morl_baselines.multi_policy.envelope.envelope import Envelope
from morl_trl.objectives import EnvelopeQLoss, make_vector_q_network
th.manual_seed(0)
env = mo_gym.make("deep-sea-treasure-v0")
mb = Envelope(env, gamma=0.99, log=False, seed=3)
ours_net = make_vector_q_network(2, 4, 2, num_cells=(256,) * 4, preference_layer=0, init="orthogonal")
loss = EnvelopeQLoss(ours_net, num_objectives=2, num_preference_samples=4)
loss.make_value_estimator(gamma=0.99)
mb_lin = [m for m in mb.q_net.modules() if isinstance(m, th.nn.Linear)]
mb_tgt = [m for m in mb.target_q_net.modules() if isinstance(m, th.nn.Linear)]
# a target network different from the online one: perturb MB's and copy both into ours
with th.no_grad():
    for m in mb_tgt:
        m.weight.add_(0.05 * th.randn_like(m.weight)); m.bias.add_(0.05 * th.randn_like(m.bias))
def load(params, layers):
    flat = params.flatten_keys(".")
    ws = [k for k in flat.keys() if k.endswith("weight")]; bs = [k for k in flat.keys() if k.endswith("bias")]
    assert len(ws) == len(layers) == 5, (ws, len(layers))
    with th.no_grad():
        for kw, kb, m in zip(ws, bs, layers):
            assert flat[kw].shape == m.weight.shape
            flat[kw].data.copy_(m.weight); flat[kb].data.copy_(m.bias)
load(loss.value_network_params, mb_lin); load(loss.target_value_network_params, mb_tgt)
B, N = 256, 4
rng = np.random.default_rng(0)
obs = th.tensor(rng.integers(0, 11, (B, 2)), dtype=th.float32)
nobs = th.tensor(rng.integers(0, 11, (B, 2)), dtype=th.float32)
act = th.tensor(rng.integers(0, 4, (B, 1)), dtype=th.uint8)
rew = th.tensor(np.stack([rng.choice([0, 0, 0, 23.7, 8.2], B), -np.ones(B)], 1), dtype=th.float32)
term = th.tensor(rng.random((B, 1)) < 0.1, dtype=th.float32)
sampled_w = th.tensor(np.abs(rng.standard_normal((N, 2))), dtype=th.float32); sampled_w /= sampled_w.sum(1, keepdim=True)
# MB's update, inline (envelope.py update(): repeat, envelope_target, mse, clip, priorities)
w = sampled_w.repeat_interleave(B, 0)
b_obs, b_act, b_rew, b_nobs, b_done = obs.repeat(N, 1), act.repeat(N, 1), rew.repeat(N, 1), nobs.repeat(N, 1), term.repeat(N, 1)
with th.no_grad():
    target_q = b_rew + (1 - b_done) * 0.99 * mb.envelope_target(b_nobs, w, sampled_w)
qv = mb.q_net(b_obs, w)
q_value = qv.gather(1, b_act.long().reshape(-1, 1, 1).expand(qv.size(0), 1, qv.size(2))).reshape(-1, 2)
mb_loss = th.nn.functional.mse_loss(q_value, target_q)
mb.q_optim.zero_grad(); mb_loss.backward()
mb_grads = [p.grad.clone() for p in mb.q_net.parameters()]
mb_prio = th.einsum("sr,sr->s", (q_value[:B] - target_q[:B]).detach(), w[:B]).abs()
# ours
loss._preferences = lambda _: sampled_w.expand(B, N, 2)
data = TensorDict({"observation": obs, "action": act.long().squeeze(-1), ("next", "observation"): nobs,
                   ("next", "reward"): rew, ("next", "terminated"): term.bool(), ("next", "done"): term.bool()}, [B])
nv = loss._envelope_next_value(data["next"], sampled_w.expand(B, N, 2))  # [B, N, k]
ours_target = rew[:, None] + 0.99 * (1 - term[:, None]) * nv
mb_target = target_q.reshape(N, B, 2).transpose(0, 1)
out = loss(data)
out["loss_qvalue"].backward()
ours_grads = [g for g in (p.grad for p in loss.value_network_params.flatten_keys(".").values()) if g is not None]
print("targets max |diff|", float((ours_target - mb_target).abs().max()), "target range", float(mb_target.min()), float(mb_target.max()))
print("loss ours", float(out["loss_qvalue"]), "mb", float(mb_loss))
print("priorities max |diff|", float((data["td_error"] - mb_prio).abs().max()))
flat = loss.value_network_params.flatten_keys(".")
print("grads max |diff|", max(float((flat[k].grad - g).abs().max()) for k, g in zip(flat.keys(), mb_grads)))  # (same order: weight, bias per layer)
