"""MultiContextEvaluator on the deterministic ToyContextEnv, where every return is worked out by hand.

Toy dynamics (tests/mocks.py): context (speed s, bias b); action 1 moves right, 0 left;
reward [s * move + b, -1]; terminates at |position| >= 3, truncates after 6 steps.

The test policy goes straight right when the preference favours time (w[1] > 0.5), which ends
the episode after 3 steps, and otherwise alternates right/left until truncation after 6.
"""

import csv
import warnings

import numpy as np
import pytest
import torch
from tensordict.nn import TensorDictModule
from torchrl.envs import StepCounter, TransformedEnv
from torchrl.envs.utils import ExplorationType, exploration_type

from morl_trl.evaluation import MultiContextEvaluator
from morl_trl.envs.registry import DomainSpec, register_domain
from morl_trl.metrics import Bounds, hypervolume
from morl_trl.reporting import DomainReference
from tests.mocks import TOY_CONTEXT, ToyContextEnv

G = 0.9
CONTEXTS = {"a": TOY_CONTEXT.make(speed=0.5, bias=1.0), "b": TOY_CONTEXT.make(speed=2.0, bias=0.0)}
WEIGHTS = torch.tensor([[1.0, 0.0], [0.0, 1.0], [0.7, 0.3]])


def toy_factory(num_envs, seed):
    return ToyContextEnv(num_envs=num_envs, seed=seed)


def policy(td):
    t = (td["observation"][..., 1] * 10).round().long()
    alternate = (t % 2 == 0).long()  # right at even steps, left at odd ones
    td["action"] = torch.where(td["preference"][..., 1] > 0.5, torch.ones_like(alternate), alternate)
    return td


def straight(s, b):
    """Three steps right, then terminated."""
    return np.array([(s + b) * (1 + G + G**2), -(1 + G + G**2)])


def alternate(s, b):
    """Six steps right/left, then truncated."""
    return np.array([sum(G**t * (s * (-1) ** t + b) for t in range(6)), -sum(G**t for t in range(6))])


def expected_returns():
    out = np.empty((2, 3, 2))
    for c, (s, b) in enumerate([(0.5, 1.0), (2.0, 0.0)]):
        out[c, 0], out[c, 1], out[c, 2] = alternate(s, b), straight(s, b), alternate(s, b)
    return out


def make(**kw):
    kw.setdefault("weights", WEIGHTS)
    kw.setdefault("gamma", G)
    kw.setdefault("env_factory", toy_factory)
    return MultiContextEvaluator(kw.pop("policy", policy), kw.pop("contexts", CONTEXTS), **kw)


# ----------------------------------------------------------------------------- returns
def test_discounted_returns_lengths_and_fronts_by_hand():
    r = make(ref_point=[0.0, -10.0]).evaluate()
    assert r.returns.shape == (2, 3, 1, 2) and r.returns.dtype == torch.float64
    np.testing.assert_allclose(r.returns[:, :, 0].numpy(), expected_returns(), rtol=1e-6)
    assert r.lengths[:, :, 0].tolist() == [[6, 3, 6], [6, 3, 6]]
    # undiscounted: a alternating: 3 * (0.5 + 1) + 3 * (-0.5 + 1) = 6
    assert r.undiscounted_returns[0, 0, 0].tolist() == pytest.approx([6.0, -6.0])
    # context a: both behaviours are Pareto optimal; context b: alternating is dominated
    a_alt, a_str = alternate(0.5, 1.0), straight(0.5, 1.0)
    np.testing.assert_allclose(r.front("a"), [a_alt, a_str], rtol=1e-6)
    np.testing.assert_allclose(r.front("b"), [straight(2.0, 0.0)], rtol=1e-6)
    m = r.per_context["a"].metrics
    assert m["cardinality"] == 2 and r.per_context["b"].metrics["cardinality"] == 1
    hv_a = a_str[0] * (10 + a_str[1]) + (a_alt[0] - a_str[0]) * (10 + a_alt[1])
    assert m["hypervolume"] == pytest.approx(hv_a, rel=1e-6)
    # EUM over the three weights: max_F w.v
    eum_a = np.mean([max(w @ a_alt, w @ a_str) for w in WEIGHTS.double().numpy()])
    assert m["eum"] == pytest.approx(eum_a, rel=1e-6)
    assert m["sparsity"] == pytest.approx(((a_alt - a_str) ** 2).sum(), rel=1e-6)
    assert r.aggregate["cardinality"] == 1.5


def test_each_sub_env_counts_only_its_first_episode():
    # the straight episodes end at step 3 while the others run to 6; whether the finished
    # sub-envs are reset or stepped on, nothing after their first done is counted
    for reset_finished in (True, False):
        r = make(reset_finished=reset_finished).evaluate()
        np.testing.assert_allclose(r.returns[:, :, 0].numpy(), expected_returns(), rtol=1e-6)


def test_episodes_repeat_each_pair():
    full = make(episodes=3).evaluate()
    assert full.returns.shape == (2, 3, 3, 2)
    np.testing.assert_allclose(full.returns.numpy(), np.repeat(expected_returns()[:, :, None], 3, 2), rtol=1e-6)


@pytest.mark.parametrize("chunk_size", [1, 4, 5, 17])
@pytest.mark.parametrize("reset_finished", [True, False])
def test_a_smaller_pool_streams_through_the_grid_with_the_same_returns(chunk_size, reset_finished):
    # 18 rows on a pool of sub-envs: a sub-env whose episode ends (after 3 or 6 steps) is reset
    # with the context and preference of the next pending row
    ev = make(episodes=3, chunk_size=chunk_size, reset_finished=reset_finished)
    r = ev.evaluate()
    np.testing.assert_allclose(r.returns.numpy(), np.repeat(expected_returns()[:, :, None], 3, 2), rtol=1e-6)
    assert r.lengths[:, :, 0].tolist() == [[6, 3, 6], [6, 3, 6]]
    assert list(ev._envs) == [(None, chunk_size)]  # one batched env of that size


def test_a_call_may_evaluate_other_weights_on_the_same_contexts():
    """``evaluate(weights=...)``: the evaluator's contexts and episodes at the call's weights (GPI's CCS values)."""
    ev = make(episodes=2)
    r = ev.evaluate(weights=[[0.0, 1.0], [0.6, 0.4]])
    assert r.returns.shape == (2, 2, 2, 2) and r.weights.tolist() == [[0.0, 1.0], [0.6, 0.4]]
    for c, (s, b) in enumerate([(0.5, 1.0), (2.0, 0.0)]):  # straight for w[1] > 0.5, alternating otherwise
        np.testing.assert_allclose(r.returns[c, :, 0].numpy(), [straight(s, b), alternate(s, b)], rtol=1e-6)
    assert list(ev._envs) == [(None, 8)]  # one pool per evaluation: 2 contexts x 2 weights x 2 episodes
    np.testing.assert_allclose(ev.evaluate().returns[:, :, 0].numpy(), expected_returns(), rtol=1e-6)
    assert ev.evaluate().weights.tolist() == WEIGHTS.double().tolist()  # the evaluator's own are unchanged
    with pytest.raises(ValueError, match="weights"):
        ev.evaluate(weights=[[0.5, 0.6]])


def test_a_call_seed_replaces_the_evaluator_seed():
    """``evaluate(seed=s)`` draws what an evaluator built with ``seed=s`` draws (here a random policy's actions)."""
    def coin(td):
        td["action"] = torch.randint(0, 2, td["preference"].shape[:-1])
        return td

    a = make(policy=coin, seed=3).evaluate()
    b = make(policy=coin, seed=0).evaluate(seed=3)
    c = make(policy=coin, seed=0).evaluate()
    torch.testing.assert_close(a.returns, b.returns)
    assert not torch.equal(a.returns, c.returns)


def test_policy_ignoring_the_preference_single_objective_baseline():
    always_right = TensorDictModule(
        lambda obs: torch.ones(obs.shape[:-1], dtype=torch.long), in_keys=["observation"], out_keys=["action"]
    )
    r = make(policy=always_right).evaluate()
    for c, (s, b) in enumerate([(0.5, 1.0), (2.0, 0.0)]):
        np.testing.assert_allclose(r.returns[c, :, 0].numpy(), np.tile(straight(s, b), (3, 1)), rtol=1e-6)
        assert r.per_context[r.context_names[c]].metrics["cardinality"] == 1


def test_the_env_factory_composes_the_policy_transforms():
    def by_step_count(td):  # reads StepCounter's output instead of the observation
        t = td["step_count"].squeeze(-1)
        td["action"] = torch.where(td["preference"][..., 1] > 0.5, torch.ones_like(t), (t % 2 == 0).long())
        return td

    def factory(num_envs, seed):
        return TransformedEnv(ToyContextEnv(num_envs=num_envs, seed=seed), StepCounter())

    r = make(policy=by_step_count, env_factory=factory).evaluate()
    np.testing.assert_allclose(r.returns[:, :, 0].numpy(), expected_returns(), rtol=1e-6)


def test_returns_equal_a_hand_rolled_loop_on_lava_grid():
    # the library transforms (PreferenceConditioning(mode="given"), DiscountedVectorReturn) give
    # the numbers of a plain loop: step the fixed-context env, sum gamma^t r_t until the first done
    from morl_trl.envs import domain_of, make_env

    spec = domain_of("MOLavaGridDR-v0")
    names = list(spec.evaluation_ids[:2])
    weights = torch.tensor([[1.0, 0.0], [0.3, 0.7], [0.0, 1.0]])

    def fixed(td):  # a deterministic policy reading position, step and preference
        obs = td["observation"].flatten(1).float()
        score = obs.sum(-1) + 7 * td["preference"][:, 0] + 3 * td["preference"][:, 1]
        td["action"] = (score * 13).long() % 3
        return td

    ev = MultiContextEvaluator(fixed, names, weights, gamma=0.995, seed=3)
    r = ev.evaluate()
    for c, name in enumerate(names):
        env = make_env(name, num_envs=len(weights), seed=3)
        td = env.reset()
        td["preference"] = weights.clone()
        ret = torch.zeros(len(weights), 2, dtype=torch.float64)
        und = torch.zeros_like(ret)
        alive = torch.ones(len(weights), dtype=torch.bool)
        length = torch.zeros(len(weights), dtype=torch.long)
        t = 0
        while alive.any():
            td = env.step(fixed(td))
            rew = td["next", "reward"].double()
            ret += torch.where(alive[:, None], 0.995**t * rew, 0.0)
            und += torch.where(alive[:, None], rew, 0.0)
            length += alive
            alive &= ~td["next", "done"].squeeze(-1)
            td = env.step_mdp(td).set("preference", weights.clone())
            t += 1
        torch.testing.assert_close(r.returns[c, :, 0], ret, rtol=1e-9, atol=1e-9)
        torch.testing.assert_close(r.undiscounted_returns[c, :, 0], und, rtol=1e-9, atol=1e-9)
        assert r.lengths[c, :, 0].tolist() == length.tolist()
    assert r.lengths.min() > 1  # the episodes did something


def test_exploration_type_is_set_while_acting():
    seen = set()

    def pol(td):
        seen.add(exploration_type())
        td["action"] = torch.ones(td.batch_size, dtype=torch.long)
        return td

    make(policy=pol).evaluate()
    make(policy=pol, exploration_type=ExplorationType.RANDOM).evaluate()
    assert seen == {ExplorationType.DETERMINISTIC, ExplorationType.RANDOM}


def test_stochastic_policy_is_reproducible_from_the_seed():
    def coin(td):
        td["action"] = (torch.rand(td.batch_size) < 0.5).long()
        return td

    a, b, c = (make(policy=coin, seed=s, episodes=4).evaluate().returns for s in (1, 1, 2))
    torch.testing.assert_close(a, b)
    assert not torch.equal(a, c)
    before = torch.random.get_rng_state()
    make(policy=coin, seed=1).evaluate()
    assert torch.equal(before, torch.random.get_rng_state())  # the global RNG is left alone


def test_random_policy_keyword():
    r = make(policy="random", seed=0).evaluate()
    assert ((r.lengths >= 3) & (r.lengths <= 6)).all()
    assert (r.returns[..., 1] < 0).all()


# ----------------------------------------------------------------------------- registered domain + reference
TOY_DOMAIN = DomainSpec(
    name="Toy",
    train_id="ToyEvalDR-v0",
    env_class="tests.mocks:ToyContextEnv",
    context_space=TOY_CONTEXT,
    contexts={"ToyEvalA-v0": {"speed": 0.5, "bias": 1.0}, "ToyEvalB-v0": {"speed": 2.0, "bias": 0.0}},
    evaluation_ids=("ToyEvalA-v0", "ToyEvalB-v0"),
    objective_names=("progress", "time"),
    gamma=G,
    hv_ref_point=(0.0, -10.0),
    max_episode_steps=6,
)


@pytest.fixture(scope="module")
def toy_domain():
    return register_domain(TOY_DOMAIN, replace=True)


def test_registered_domain_suite_with_reference_gives_nhgr_and_eugr(toy_domain):
    a_alt, a_str, b_str = alternate(0.5, 1.0), straight(0.5, 1.0), straight(2.0, 0.0)
    # the specialist of A found a better straight return; the one of B equals ours
    spec_a = [a_alt, a_str + [1.0, 0.0]]
    ref = DomainReference(
        "ToyEvalDR-v0",
        {"ToyEvalA-v0": Bounds([0.0, -7.0], [7.0, 0.0]), "ToyEvalB-v0": Bounds([0.0, -7.0], [7.0, 0.0])},
        {"ToyEvalA-v0": spec_a, "ToyEvalB-v0": [b_str]},
    )
    ev = MultiContextEvaluator(policy, "ToyEvalDR-v0", WEIGHTS, reference=ref)
    assert ev.gamma == G and ev.context_names == ("ToyEvalA-v0", "ToyEvalB-v0")
    r = ev.evaluate()
    assert r.objective_names == ("progress", "time") and r.context_parameters == ("speed", "bias")
    np.testing.assert_allclose(r.returns[:, :, 0].numpy(), expected_returns(), rtol=1e-6)

    def nhv(points):  # normalized to [0,7] x [-7,0]
        n = (np.asarray(points) - [0.0, -7.0]) / 7.0
        n = n[np.argsort(-n[:, 0])]
        return n[0, 0] * n[0, 1] + sum(n[i, 0] * max(0.0, n[i, 1] - n[:i, 1].max()) for i in range(1, len(n)))

    nhgr_a = nhv([a_alt, a_str]) / nhv(spec_a)
    m = r.per_context["ToyEvalA-v0"].metrics
    assert m["nhgr"] == pytest.approx(nhgr_a, rel=1e-6) and nhgr_a < 1
    assert r.per_context["ToyEvalB-v0"].metrics["nhgr"] == pytest.approx(1.0, rel=1e-6)
    assert m["normalized_hypervolume"] == pytest.approx(nhv([a_alt, a_str]), rel=1e-6)
    assert r.aggregate["nhgr"] == pytest.approx((nhgr_a + 1) / 2, rel=1e-6)
    assert r.aggregate["nhgr_optimality_gap"] == pytest.approx(1 - (nhgr_a + 1) / 2, rel=1e-6)
    assert 0 < m["eugr"] < 1 and r.per_context["ToyEvalB-v0"].metrics["eugr"] == pytest.approx(1.0, rel=1e-6)
    # the domain's HV reference point was used
    assert m["hypervolume"] == pytest.approx(hypervolume([a_alt, a_str], [0.0, -10.0]), rel=1e-9)


def test_default_weights_are_the_papers_energy_weights(toy_domain):
    ev = MultiContextEvaluator(policy, ["ToyEvalB-v0"])
    assert ev.weights.shape == (100, 2)
    assert ev.weights[:2].flatten().tolist() == pytest.approx([0.0, 1.0, 0.00997283524824734, 0.9900271647517526])
    r = ev.evaluate()
    assert r.returns.shape == (1, 100, 1, 2)
    # w[1] > 0.5 goes straight: 50 of the 100 energy weights
    assert int((r.lengths == 3).sum()) == int((ev.weights[:, 1] > 0.5).sum()) == 50


def test_rows_for_csv_logging_name_every_objective(tmp_path):
    r = make(episodes=2).evaluate()
    rows = r.to_rows()
    assert len(rows) == 2 * 3 * 2
    assert rows[2] == pytest.approx(
        {
            "context": "a", "weight_index": 1, "episode": 0, "weight_progress": 0.0, "weight_time": 1.0,
            "return_progress": straight(0.5, 1.0)[0], "return_time": straight(0.5, 1.0)[1],
            "undiscounted_return_progress": 4.5, "undiscounted_return_time": -3.0, "length": 3,
            # the toy's original_reward is progress + time (f_SORL)
            "sorl_return": 1.5, "sorl_discounted_return": sum(straight(0.5, 1.0)),
        }
    )
    metric_rows = r.metric_rows()
    assert [m["context"] for m in metric_rows] == ["a", "b"]
    assert metric_rows[1]["speed"] == 2.0 and metric_rows[1]["bias"] == 0.0
    assert r.front_rows()[0].keys() == {"context", "progress", "time"}
    path = r.write_csv(tmp_path / "episodes.csv")
    with path.open() as fh:
        assert len(list(csv.DictReader(fh))) == 12
    s = r.summary()
    assert s["eval/cardinality/a"] == 2.0 and s["eval/cardinality/mean"] == 1.5
    assert "eval/hypervolume/a" not in s  # no reference point, no HV: left out, not 0


# ----------------------------------------------------------------------------- bad input
@pytest.mark.parametrize(
    "kwargs, match",
    [
        (dict(weights=torch.tensor([[0.5, 0.6]])), r"weights row 0 = \[0.5, 0.6\] sums to 1.1; weights must lie on the simplex"),
        (dict(weights=torch.tensor([[1.0, 0.0, 0.0]])), r"weights has shape \(1, 3\); expected \[\.\.\., 2\]"),
        (dict(weights=torch.tensor([[float("nan"), 1.0]])), "finite"),
        (dict(eum_weights=torch.tensor([[2.0, -1.0]])), "negative"),
        (dict(episodes=0), "episodes"),
        (dict(chunk_size=0), "chunk_size"),
        (dict(gamma=1.5), "gamma"),
        (dict(gamma=None), "pass gamma"),
        (dict(ref_point=[0.0]), "ref_point"),
        (dict(bounds={"zz": ([0, 0], [1, 1])}), "not evaluated"),
        (dict(bounds={"a": ([0, 0], [0, 1])}), "upper must be > lower"),
        (dict(contexts={}), "empty"),
        (dict(contexts={"a": torch.tensor([1.0, float("nan")])}), "finite"),
        (dict(policy=42), "policy"),
        (
            dict(reference=DomainReference("T", {"a": ([0, 0], [1, 1])}, {"a": [[1.0, 1.0]]})),
            r"no data for contexts \['b'\]",
        ),
    ],
)
def test_bad_arguments_raise(kwargs, match):
    with pytest.raises(ValueError, match=match):
        make(**kwargs)


def test_bad_context_ids_raise(toy_domain):
    with pytest.raises(ValueError, match="unknown env id"):
        MultiContextEvaluator(policy, ["ToyEvalA-v0", "NoSuchEnv-v0"])
    with pytest.raises(ValueError, match="several domains"):
        MultiContextEvaluator(policy, ["ToyEvalA-v0", "MOLunarLanderHard-v0"])
    with pytest.raises(ValueError, match="env_factory"):
        MultiContextEvaluator(policy, CONTEXTS, gamma=G)


def test_max_steps_cuts_with_a_warning():
    with warnings.catch_warnings(record=True) as w:
        warnings.simplefilter("always")
        r = make(max_steps=2).evaluate()
    assert any("still running" in str(x.message) for x in w)
    assert (r.lengths == 2).all()


# ----------------------------------------------------------------------------- the env factory
def test_a_stack_that_redraws_contexts_is_refused_not_mislabelled():
    from morl_trl.transforms import DomainRandomization

    def training_stack(num_envs, seed):
        return TransformedEnv(ToyContextEnv(num_envs=num_envs, seed=seed), DomainRandomization(TOY_CONTEXT, seed=0))

    ev = make(env_factory=training_stack)
    with pytest.raises(ValueError, match=r"gave 'a' = \[0.5, 1.0\] in the reset TensorDict: something in its stack "
                                         r"draws its own contexts at reset \(e.g. a DomainRandomization"):
        ev.evaluate()


def test_the_pool_checks_the_contexts_of_later_partial_resets_too():
    class FirstResetOnly(ToyContextEnv):  # honours the given context at the first reset only
        def _reset(self, tensordict=None, **kwargs):
            if getattr(self, "_seen", False) and tensordict is not None and "context" in tensordict.keys():
                tensordict = tensordict.clone().set("context", torch.zeros_like(tensordict["context"]) + 0.25)
            self._seen = True
            return super()._reset(tensordict, **kwargs)

    ev = make(env_factory=lambda num_envs, seed: FirstResetOnly(num_envs=num_envs, seed=seed), chunk_size=2)
    with pytest.raises(ValueError, match=r"reset a sub-env to context \[0.25, 0.25\]"):
        ev.evaluate()


@pytest.mark.parametrize(
    "factory, match",
    [
        (StepCounter(), r"env_factory must be a callable \(num_envs, seed\) -> env; got a Transform \(StepCounter\): "
                        r"compose it in your factory, e.g."),
        (ToyContextEnv(num_envs=2), r"got an env instance \(ToyContextEnv\), not a function building one"),
        (42, r"env_factory must be a callable .* got env_factory=42"),
        (lambda num_envs, seed: 42, "env_factory returned int; it must return a TorchRL EnvBase"),
        (lambda num_envs, seed: ToyContextEnv(num_envs=1), r"built an env of batch size \(1,\); expected \(18,\)"),
    ],
)
def test_bad_env_factories_raise_clearly(factory, match):
    with pytest.raises(ValueError, match=match):
        make(env_factory=factory, episodes=3).evaluate()


def test_a_training_preference_in_the_stack_is_refused():
    from morl_trl.transforms import PreferenceConditioning

    def factory(num_envs, seed):
        return TransformedEnv(ToyContextEnv(num_envs=num_envs, seed=seed), PreferenceConditioning(seed=0))

    with pytest.raises(ValueError, match=r"already writes 'preference' \(a training PreferenceConditioning\?\)"):
        make(env_factory=factory).evaluate()


def test_the_transform_keyword_is_gone():
    with pytest.raises(TypeError, match="transform"):
        make(transform=lambda: StepCounter())


def test_contexts_as_env_factories_and_a_single_default_context():
    # no context vector: one env per named context, or the env as it is
    per_ctx = {
        name: (lambda num_envs, seed, c=c: ToyContextEnv(num_envs=num_envs, seed=seed, context=c))
        for name, c in CONTEXTS.items()
    }
    r = MultiContextEvaluator(policy, per_ctx, WEIGHTS, gamma=G).evaluate()
    assert r.context_names == ("a", "b") and r.context_parameters == ()
    np.testing.assert_allclose(r.returns[:, :, 0].numpy(), expected_returns(), rtol=1e-6)
    single = MultiContextEvaluator(
        policy, None, WEIGHTS, gamma=G, env_factory=lambda num_envs, seed: per_ctx["b"](num_envs, seed)
    ).evaluate()
    assert single.context_names == ("default",)
    np.testing.assert_allclose(single.returns[0, :, 0].numpy(), expected_returns()[1], rtol=1e-6)


def test_mo_gymnasium_lunar_lander_in_a_serial_env():
    mo_gym = pytest.importorskip("mo_gymnasium")
    pytest.importorskip("Box2D")
    from torchrl.envs import GymWrapper, SerialEnv

    def one():
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # Gymnasium's float64 Box bounds
            return GymWrapper(mo_gym.make("mo-lunar-lander-v3"))

    def factory(num_envs, seed):
        return SerialEnv(num_envs, one)  # no device given: the evaluator must not need env.device

    weights = torch.tensor([[1.0, 0.0, 0.0, 0.0], [0.25, 0.25, 0.25, 0.25], [0.0, 0.5, 0.5, 0.0]])
    runs = []
    for _ in range(2):
        ev = MultiContextEvaluator("random", {"default": factory}, weights, gamma=0.99, seed=5)
        runs.append(ev.evaluate())
        ev.close()
    r = runs[0]
    assert r.returns.shape == (1, 3, 1, 4) and torch.isfinite(r.returns).all()
    assert ((r.lengths >= 40) & (r.lengths <= 1000)).all()  # random landers crash or drift off
    front = r.front("default")
    assert 1 <= len(front) <= 3 and np.isfinite(front).all()
    assert r.per_context["default"].metrics["cardinality"] == len(front)
    torch.testing.assert_close(runs[1].returns, r.returns)  # deterministic for a seed
