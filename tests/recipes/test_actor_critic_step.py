"""The actor-critics' update (issues 26 and 27): critic step, then actor step(s), then the temperature, each
loss computed alone (``qvalue_loss`` / ``actor_loss`` / ``temperature_loss``), as the authors' CleanRL-style
SAC and MORL-Baselines' MOSAC (``mosac_continuous_action.py:460-482``) do."""

import math

import pytest
import torch
from torchrl.data import Bounded

from morl_trl.objectives import MOSACLoss, PopulationMOSACLoss
from morl_trl.objectives.networks import make_gaussian_actor, make_vector_critic
from morl_trl.objectives.population import make_population_critic, make_population_gaussian_actor
from morl_trl.objectives.sac import SACLoss
from morl_trl.recipes import build_agent, build_training_env, resolve_config
from morl_trl.algorithms.actor_critic.recipe import policy_freq, steps_each_loss
from morl_trl.recipes.off_policy import make_replay_buffer
from tests.objectives._helpers import random_batch

pytestmark = pytest.mark.filterwarnings("ignore:No target network updater")

CPU = torch.device("cpu")


def _agent(algo, env_id, **kw):
    torch.manual_seed(0)
    cfg = resolve_config(algo, env_id, quick=True, hidden=(16,), batch_size=8, buffer_size=1024, progress=False, **kw)
    env = build_training_env(cfg, CPU)
    agent = build_agent(cfg, env, gamma=0.99, device=CPU)
    buffer = make_replay_buffer(cfg, CPU)
    buffer.extend(env.rollout(8, break_when_any_done=False).reshape(-1))
    return agent, buffer


def _record(agent):
    """Wraps the loss's parts, its target computation and the optimizers' steps; returns the event list."""
    events = []
    loss = agent.loss

    def wrap(obj, name, label):
        fn = getattr(obj, name)

        def wrapped(*args, **kwargs):
            events.append(label(*args, **kwargs) if callable(label) else label)
            return fn(*args, **kwargs)
        setattr(obj, name, wrapped)

    wrap(loss, "qvalue_loss", "Q")
    wrap(loss, "actor_loss", "A")
    if hasattr(loss, "actor_dist"):
        wrap(loss, "actor_dist", "D")
    wrap(loss, "temperature_loss", lambda td, log_prob=None, dist=None: "T(fresh)" if log_prob is None else "T(reused)")
    wrap(loss.value_estimator, "value_estimate", "target")
    for name, opt in agent.optimizers.items():
        wrap(opt, "step", f"step:{name}")
    return events


def _updates(agent, buffer, n):
    """``n`` of the recipe's updates (:func:`morl_trl.algorithms.actor_critic.recipe.update`; MORL/D's off the shared clock,
    the acting member's own, :func:`morl_trl.algorithms.morld.recipe.update`)."""
    from morl_trl.algorithms.actor_critic import recipe as actor_critic
    from morl_trl.algorithms.morld import recipe as morld

    if agent.cfg.algo == "morld":
        morld.updates_at(agent, buffer, [None] * n)
    else:
        for _ in range(n):
            actor_critic.update(agent, buffer)


@pytest.mark.parametrize("algo", ["sac", "morld", "mosac"])
def test_the_delayed_actor_runs_critic_then_two_actor_and_fresh_temperature_steps(algo, single_thread):
    """policy_freq 2: update 1 is a critic step alone; update 2 a critic step then two (actor step,
    temperature step on a fresh sample of the updated actor) pairs; the target is computed once per
    update, never in an actor step (before: the whole loss three times on an actor turn). The first
    temperature's sample and the second actor step's come from one forward of the actor (``D``)."""
    pytest.importorskip("mujoco")
    agent, buffer = _agent(algo, "MOHopperDR-v5")
    assert policy_freq(agent) == 2 and steps_each_loss(agent)
    events = _record(agent)
    _updates(agent, buffer, 2)
    critic = ["Q", "target", "step:qvalue"]
    assert events == critic + critic + ["A", "step:actor", "D", "T(fresh)", "step:alpha",
                                        "A", "step:actor", "T(fresh)", "step:alpha"]
    events.clear()
    _updates(agent, buffer, 4)  # 6 updates: 6 critic steps and targets, 3 actor turns of 2
    assert events.count("target") == 4 and events.count("step:qvalue") == 4
    assert events.count("step:actor") == 4 and events.count("step:alpha") == 4


def test_discrete_sac_steps_critic_actor_temperature_on_the_actor_steps_probabilities(single_thread):
    """The authors' discrete SAC / MOSACDiscrete: each update a critic step, an actor step on the updated
    critics and a temperature step on the actor step's probabilities (reused, not re-drawn)."""
    agent, buffer = _agent("sac", "MOLavaGridDR-v0")
    assert policy_freq(agent) == 1
    events = _record(agent)
    _updates(agent, buffer, 3)
    assert events == ["Q", "target", "step:qvalue", "A", "step:actor", "T(reused)", "step:alpha"] * 3


def test_capql_steps_critics_then_actor_and_joint_update_keeps_one_step(single_thread):
    """CAPQL (MB's capql.py:336-350): the critic step, then the actor on the updated critics; fixed temperature.
    ``joint_update=true`` is the earlier single step of the summed losses (forward, one backward)."""
    pytest.importorskip("mujoco")
    agent, buffer = _agent("capql", "MOHopperDR-v5")
    events = _record(agent)
    _updates(agent, buffer, 2)
    assert events == ["Q", "target", "step:qvalue", "A", "step:actor"] * 2
    joint, buffer = _agent("capql", "MOHopperDR-v5", joint_update=True)
    assert not steps_each_loss(joint)
    events = _record(joint)
    _updates(joint, buffer, 2)
    assert events == ["target", "step:actor", "step:qvalue"] * 2  # forward (its target), then both optimizers
    with pytest.raises(ValueError, match="joint_update=true steps every loss together"):
        _agent("sac", "MOHopperDR-v5", joint_update=True)


def test_each_algorithm_takes_the_authors_temperature_loss_form():
    """SAC: CleanRL's ``-log_alpha.exp() * (...)``; MORL/D's continuous MOSAC members and standalone MOSAC:
    MORL-Baselines' ``-self.log_alpha * (...)`` (mosac_continuous_action.py:470); MOSACDiscrete: ``-alpha``."""
    forms = {(a, e): resolve_config(a, e).alpha_loss_form for a, e in [
        ("sac", "MOHopperDR-v5"), ("sac", "MOLunarLanderDR-v0"), ("morld", "MOHopperDR-v5"),
        ("morld", "MOLunarLanderDR-v0"), ("morld_psa", "MOHalfCheetahDR-v5"), ("mosac", "MOHopperDR-v5"),
        ("mosac_discrete", "MOLavaGridDR-v0")]}
    assert forms == {("sac", "MOHopperDR-v5"): "alpha", ("sac", "MOLunarLanderDR-v0"): "alpha",
                     ("morld", "MOHopperDR-v5"): "log_alpha", ("morld", "MOLunarLanderDR-v0"): "alpha",
                     ("morld_psa", "MOHalfCheetahDR-v5"): "log_alpha", ("mosac", "MOHopperDR-v5"): "log_alpha",
                     ("mosac_discrete", "MOLavaGridDR-v0"): "alpha"}


def _losses(form):
    spec = Bounded(-1.0, 1.0, (2,))
    torch.manual_seed(0)
    mosac = MOSACLoss(make_gaussian_actor(5, spec, 2, num_cells=(8,)), make_vector_critic(5, 2, 2, num_cells=(8,)),
                      alpha_init=0.5, alpha_loss_form=form, action_spec=spec)
    sac = SACLoss(make_gaussian_actor(5, spec, 1, num_cells=(8,), preference_key=None),
                  make_vector_critic(5, 2, 1, num_cells=(8,), preference_key=None), alpha_init=0.5, action_spec=spec,
                  alpha_loss_form=form)
    pop = PopulationMOSACLoss(make_population_gaussian_actor(1, 5, spec, num_cells=(8,)),
                              make_population_critic(1, 5, 2, 2, num_cells=(8,)), weights=torch.tensor([[0.5, 0.5]]),
                              alpha_init=0.5, alpha_loss_form=form)
    return mosac, sac, pop


@pytest.mark.parametrize("form, value", [("alpha", 0.25), ("log_alpha", 0.5 * math.log(0.5))])
def test_the_temperature_loss_is_the_formula_on_a_known_log_prob(form, value):
    """alpha = 0.5, target entropy -2, log-probs [1, 2]: mean(log pi + target) = -0.5, so
    ``-alpha * -0.5 = 0.25`` ("alpha") and ``-log(0.5) * -0.5 = 0.5 ln 0.5`` ("log_alpha"); the gradient on
    log alpha is the same number for "alpha" (d(-e^x m)/dx = -e^x m) and 0.5 for "log_alpha"."""
    for loss in _losses(form):
        batch = (1, 2) if isinstance(loss, PopulationMOSACLoss) else (2,)
        data = random_batch(2, 5, 1 if isinstance(loss, SACLoss) else 2, action_dim=2)
        if len(batch) == 2:
            data = data.unsqueeze(0)
        log_prob = torch.tensor([1.0, 2.0]).reshape(batch)
        out = loss.temperature_loss(data, log_prob)
        assert out.item() == pytest.approx(value, abs=1e-6), type(loss).__name__
        out.backward()
        assert loss.log_alpha.grad.sum().item() == pytest.approx(0.25 if form == "alpha" else 0.5, abs=1e-6)


@pytest.mark.parametrize("fast", [True, False])
def test_the_parts_are_forwards_losses_from_the_same_random_state(fast):
    """``qvalue_loss`` then ``actor_loss`` draw what ``forward`` draws, in its order: the same values."""
    spec = Bounded(-1.0, 1.0, (2,))
    loss = MOSACLoss(make_gaussian_actor(5, spec, 2, num_cells=(8,)), make_vector_critic(5, 2, 2, num_cells=(8,)),
                     action_spec=spec)
    loss.fast_networks = fast
    loss.make_value_estimator(gamma=0.9)
    data = random_batch(16, 5, 2, action_dim=2)
    torch.manual_seed(3)
    out = loss(data.clone())
    torch.manual_seed(3)
    q, meta_q = loss.qvalue_loss(data)
    a, meta_a = loss.actor_loss(data)
    torch.testing.assert_close(q, out["loss_qvalue"])
    torch.testing.assert_close(a, out["loss_actor"])
    torch.testing.assert_close(loss.temperature_loss(data, meta_a["log_prob"]), out["loss_alpha"])
    torch.testing.assert_close(-meta_a["log_prob"].mean(), out["entropy"])
    assert data["td_error"].shape == (16,) and torch.equal(data["td_error"], meta_q["td_error"])


@pytest.mark.parametrize("which", ["mosac_fast", "mosac", "sac", "population"])
def test_one_actor_forward_shared_by_temperature_and_actor_step_draws_what_two_forwards_draw(which):
    """``temperature_loss(dist=d)`` then ``actor_loss(dist=d)`` with ``d = actor_dist(td)`` equal the two
    calls with their own forwards from the same random state (the network is unchanged in between)."""
    mosac, sac, pop = _losses("log_alpha")
    loss = {"mosac_fast": mosac, "mosac": mosac, "sac": sac, "population": pop}[which]
    if which == "mosac":
        loss.fast_networks = False
    data = random_batch(8, 5, 1 if which == "sac" else 2, action_dim=2)
    if which == "population":
        data = data.unsqueeze(0)
    torch.manual_seed(7)
    t_two, (a_two, meta_two) = loss.temperature_loss(data), loss.actor_loss(data)
    torch.manual_seed(7)
    dist = loss.actor_dist(data)
    t_one, (a_one, meta_one) = loss.temperature_loss(data, dist=dist), loss.actor_loss(data, dist)
    torch.testing.assert_close(t_one, t_two)
    torch.testing.assert_close(a_one, a_two)
    torch.testing.assert_close(meta_one["log_prob"], meta_two["log_prob"])
    a_one.backward()  # the shared forward carries the actor's gradient
    assert any(p.grad is not None and p.grad.abs().sum() > 0 for p in loss.actor_network_params.values(True, True))
