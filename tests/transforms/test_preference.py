import pickle

import pytest
import torch
from tensordict import TensorDict
from torchrl.envs import TransformedEnv
from torchrl.envs.utils import check_env_specs

from morl_trl.transforms import DomainRandomization, PreferenceConditioning
from morl_trl.preferences import sample_preferences
from tests.mocks import TOY_CONTEXT, ToyContextEnv
from tests.transforms.helpers import ScriptedPolicy, episode_starts

W2 = [[1.0, 0.0], [0.5, 0.5]]


def make(n=3, **kwargs):
    return TransformedEnv(ToyContextEnv(num_envs=n), PreferenceConditioning(**kwargs))


def test_dirichlet_default_on_simplex_per_subenv_constant_per_episode():
    n, steps = 4, 20
    env = make(n, seed=0)
    assert env.transform.num_objectives == 2  # inferred from the reward spec
    td = env.rollout(steps, ScriptedPolicy((n,), steps, seed=1), break_when_any_done=False)
    w = td["preference"]
    assert torch.equal(td["next", "preference"], w)
    assert (w >= 0).all() and torch.allclose(w.sum(-1), torch.ones(n, steps))
    assert w[:, 0].unique(dim=0).shape[0] == n
    starts = episode_starts(td)
    same = (w[:, 1:] == w[:, :-1]).all(-1)
    assert torch.equal(same, ~starts[:, 1:])


def test_partial_reset_only_redraws_reset_subenvs():
    env = make(3, seed=0)
    td = env.reset()
    before = td["preference"].clone()
    after = env.reset(td.set("_reset", torch.tensor([[False], [True], [False]])))["preference"]
    assert torch.equal(after[[0, 2]], before[[0, 2]]) and not torch.equal(after[1], before[1])


def test_seeded_and_follows_env_seed_and_independent_of_contexts():
    a = make(3, seed=7).reset()["preference"]
    b = make(3, seed=7).reset()["preference"]
    assert torch.equal(a, b)
    env = TransformedEnv(ToyContextEnv(num_envs=3, seed=7), PreferenceConditioning())
    assert torch.equal(env.reset()["preference"], a)  # no seed: the env's
    env.set_seed(8)
    assert torch.equal(env.reset()["preference"], make(3, seed=8).reset()["preference"])
    # same seed for contexts and preferences: the two streams are not the same uniforms
    g = torch.Generator().manual_seed(7)
    plain = sample_preferences(3, 2, generator=g)
    assert not torch.allclose(plain, a)


def test_alpha_option_changes_the_spread():
    env = make(1, seed=0, alpha=50.0)
    draws = torch.stack([env.reset()["preference"][0] for _ in range(200)])
    assert (draws - 0.5).abs().max() < 0.25  # concentrated at the centre


def test_cycle_mode_walks_the_weight_set_across_resets():
    env = make(3, weights=W2)
    td = env.reset()
    assert td["preference"].tolist() == [[1.0, 0.0], [0.5, 0.5], [1.0, 0.0]]
    td = env.reset(td.set("_reset", torch.tensor([[False], [True], [True]])))
    assert td["preference"].tolist() == [[1.0, 0.0], [0.5, 0.5], [1.0, 0.0]]  # rows 1, 0 continue the cycle
    td = env.reset(td.set("_reset", torch.tensor([[True], [False], [False]])))
    assert td["preference"].tolist() == [[0.5, 0.5], [0.5, 0.5], [1.0, 0.0]]


def test_random_mode_draws_rows_of_the_set():
    weights = [[1.0, 0.0], [0.0, 1.0], [0.25, 0.75]]
    env = make(64, weights=weights, mode="random", seed=3)
    w = env.reset()["preference"]
    rows = [weights.index(r) for r in w.tolist()]
    assert set(rows) == {0, 1, 2}
    assert torch.equal(make(64, weights=weights, mode="random", seed=3).reset()["preference"], w)


def test_given_mode_uses_the_reset_tensordict_and_keeps_it_over_auto_resets():
    n, steps = 3, 16
    env = make(n, mode="given")
    assert env.reset()["preference"].tolist() == [[0.5, 0.5]] * n  # nothing given yet: equal weights
    w = torch.tensor([[1.0, 0.0], [0.2, 0.8], [0.0, 1.0]])
    td = env.reset(TensorDict(preference=w, batch_size=[n]))
    assert torch.equal(td["preference"], w)
    td = env.rollout(steps, ScriptedPolicy((n,), steps, seed=1), auto_reset=False, tensordict=td,
                     break_when_any_done=False)
    assert episode_starts(td)[:, 1:].any()
    assert torch.equal(td["preference"], w.unsqueeze(1).expand(n, steps, 2))
    # a partial reset takes the given preference of the sub-envs being reset only
    td = td[:, -1]["next"].clone()
    td["preference"][0] = torch.tensor([0.3, 0.7])
    td = env.reset(td.set("_reset", torch.tensor([[True], [False], [False]])))
    assert torch.allclose(td["preference"], torch.tensor([[0.3, 0.7], [0.2, 0.8], [0.0, 1.0]]))


@pytest.mark.parametrize(
    "w, match",
    [
        (torch.tensor([[0.2, 0.3, 0.5]] * 2), r"shape \(2, 3\); expected \[\.\.\., 2\]"),
        (torch.tensor([[0.5, 0.5], [1.5, -0.5]]), r"preference row 1 = \[1.5, -0.5\] has a negative weight -0.5"),
        (torch.tensor([[0.5, 0.6], [0.5, 0.5]]), r"preference row 0 = \[0.5, 0.6\] sums to 1.1"),
        (torch.tensor([[float("nan"), 1.0]] * 2), r"preference row 0 = \[nan, 1.0\] is not finite"),
    ],
)
def test_given_mode_rejects_off_simplex_preferences_and_changes_nothing(w, match):
    env = make(2, mode="given")
    td = env.reset(TensorDict(preference=torch.tensor([[0.25, 0.75]] * 2), batch_size=[2]))
    td = env.step(td.set("action", torch.tensor([1, 1])))["next"]
    with pytest.raises(ValueError, match=match):
        env.reset(TensorDict(preference=w, batch_size=[2]))
    assert env.base_env._step_count.tolist() == [1, 1]  # the env underneath was not reset
    td = env.step(td.set("action", torch.tensor([1, 1])))
    assert td["next", "preference"].tolist() == [[0.25, 0.75]] * 2
    assert td["next", "observation"][:, 0].tolist() == [2, 2]


def test_bad_constructor_arguments():
    with pytest.raises(ValueError, match=r"weight set row 1 = \[0.5, 0.6\] sums to 1.1"):
        PreferenceConditioning(weights=[[1.0, 0.0], [0.5, 0.6]])
    with pytest.raises(ValueError, match=r"weight set row 0 = \[-0.5, 1.5\] has a negative weight"):
        PreferenceConditioning(weights=[[-0.5, 1.5]])
    with pytest.raises(ValueError, match="pass weights="):
        PreferenceConditioning(2, mode="cycle")
    with pytest.raises(ValueError, match="mode must be one of"):
        PreferenceConditioning(2, mode="uniform")
    with pytest.raises(ValueError, match="alpha must be a positive"):
        PreferenceConditioning(2, alpha=0.0)
    with pytest.raises(ValueError, match="num_objectives must be a positive int"):
        PreferenceConditioning(0)
    with pytest.raises(ValueError, match="the weight set has 3 objectives; the env has 2"):
        make(2, weights=[[0.2, 0.3, 0.5]]).reset()
    with pytest.raises(ValueError, match="num_objectives gives 3 objectives; the env has 2"):
        make(2, num_objectives=3).reset()


def test_specs_and_check_env_specs():
    env = make(3, seed=0)
    spec = env.observation_spec["preference"]
    assert spec.shape == (3, 2) and spec.space.low.min() == 0 and spec.space.high.max() == 1
    assert "preference" in env.state_spec.keys()
    check_env_specs(env)
    check_env_specs(make(3, mode="given"))


def test_works_with_domain_randomization_and_pickles():
    env = TransformedEnv(ToyContextEnv(num_envs=2), DomainRandomization(TOY_CONTEXT, seed=0))
    env.append_transform(PreferenceConditioning(seed=0))
    td = env.reset()
    assert td["preference"].shape == (2, 2) and td["context"].shape == (2, 2)
    t = PreferenceConditioning(2, seed=4)
    t.sample(2)
    clone = pickle.loads(pickle.dumps(t))
    torch.testing.assert_close(clone.sample(3), t.sample(3))


# ---------------------------------------------------------------- the authors' training preferences
def _copy(generator: torch.Generator) -> torch.Generator:
    g = torch.Generator()
    g.set_state(generator.get_state())
    return g


@pytest.mark.parametrize("mode", ["dirichlet", "gaussian"])
def test_sampling_modes_draw_exactly_the_samplers_stream(mode):
    # "dirichlet" keeps the stream it always had; "gaussian" is MORL-Baselines' |N(0, I)| normalised
    env = make(4, seed=3, mode=mode)
    env.transform._sync_seed()
    expected = sample_preferences(4, 2, distribution=mode, generator=_copy(env.transform.generator))
    assert torch.equal(env.reset()["preference"], expected)


def test_envelope_training_preferences_are_gaussian_per_episode_as_the_authors():
    n, steps = 3, 12
    env = make(n, seed=0, mode="gaussian")
    td = env.rollout(steps, ScriptedPolicy((n,), steps, seed=1), break_when_any_done=False)
    w = td["preference"]
    assert (w >= 0).all() and torch.allclose(w.sum(-1), torch.ones(n, steps))
    same = (w[:, 1:] == w[:, :-1]).all(-1)
    assert torch.equal(same, ~episode_starts(td)[:, 1:])  # constant within an episode


def test_capql_acting_preference_changes_every_step_within_the_cone():
    from morl_trl.preferences import sample_cone_preferences

    n, steps, k = 3, 6, 2
    env = make(n, seed=0, mode="cone", resample="step")
    td = env.reset()
    angles, seen = [], []
    for _ in range(steps):
        g = _copy(env.transform.generator)
        acting = td["preference"].clone()
        td = env.step(td.set("action", env.action_spec.rand()))
        fresh, centre = sample_cone_preferences(n, k, generator=g, return_centre=True)
        # the w written under "next" is this step's fresh cone draw: the policy acts on it next step
        assert torch.equal(td["next", "preference"], fresh)
        assert torch.equal(td["preference"], acting)  # the transition keeps the w its action was chosen with
        cos = (fresh * centre).sum(-1) / fresh.norm(dim=-1)
        angles.append(torch.rad2deg(torch.arccos(cos.clamp(max=1.0))))
        seen.append(fresh)
        td = env.step_mdp(td) if hasattr(env, "step_mdp") else td["next"]
    seen = torch.stack(seen)  # [steps, n, k]
    # a new draw every step (two draws clipped onto the same vertex of the simplex can coincide)
    assert (seen[1:] != seen[:-1]).any(-1).any(-1).all()
    assert all(len({tuple(r.tolist()) for r in seen[:, i]}) >= steps - 1 for i in range(n))
    assert (seen >= 0).all() and torch.allclose(seen.sum(-1), torch.ones(steps, n))
    assert torch.stack(angles).max() <= 22.5 + 1e-3


def test_step_resampling_is_stored_in_rollouts_and_rejects_given():
    n, steps = 2, 5
    env = make(n, seed=1, mode="cone", resample="step")
    td = env.rollout(steps, ScriptedPolicy((n,), steps, seed=1), break_when_any_done=False)
    assert torch.equal(td["next", "preference"][:, :-1], td["preference"][:, 1:])
    assert (td["preference"][:, 1:] != td["preference"][:, :-1]).any(-1).any(0).all()
    with pytest.raises(ValueError, match="mode='given' keeps the preference"):
        PreferenceConditioning(2, mode="given", resample="step")
    with pytest.raises(ValueError, match="resample must be one of"):
        PreferenceConditioning(2, resample="always")
    assert "resample='step'" in repr(env.transform)


def test_a_next_preference_goes_once_to_each_sub_envs_next_episode_and_draws_nothing_for_it():
    """GPI-LS's first episode of an iteration (SPEC §6): ``set_next_preference(w)`` gives ``w`` to each sub-env's
    next episode, partial resets included, then the mode again; the episodes that got ``w`` draw nothing, so the
    mode's stream goes on where it was."""
    weights = [[1.0, 0.0], [0.0, 1.0], [0.25, 0.75]]
    env = make(3, weights=weights, mode="random", seed=3)
    plain = make(3, weights=weights, mode="random", seed=3)
    td, ref = env.reset(), plain.reset()
    assert torch.equal(td["preference"], ref["preference"])
    env.transform.set_next_preference([0.5, 0.5])
    td = env.reset(td.set("_reset", torch.tensor([[False], [True], [False]])))  # sub-env 1 first
    assert td["preference"][1].tolist() == [0.5, 0.5]
    assert torch.equal(td["preference"][[0, 2]], ref["preference"][[0, 2]])
    td = env.reset()  # all three: 0 and 2 get w now, 1 draws the mode's first row
    assert td["preference"][[0, 2]].tolist() == [[0.5, 0.5], [0.5, 0.5]]
    assert td["preference"][1].tolist() == plain.transform.sample(1)[0].tolist()
    assert env.transform._first is None  # (every sub-env had it)
    assert torch.equal(env.reset()["preference"], plain.transform.sample(3))  # the mode's stream, in step
    env.transform.set_next_preference([0.0, 1.0])
    env.transform.set_next_preference(None)  # withdrawn before any reset
    assert torch.equal(env.reset()["preference"], plain.transform.sample(3))


def test_a_next_preference_off_the_simplex_or_in_given_mode_is_refused_naming_it():
    env = make(2, seed=0)
    with pytest.raises(ValueError, match=r"next preference row 0 = \[0.7, 0.7\] sums to 1.4"):
        env.transform.set_next_preference([0.7, 0.7])
    with pytest.raises(ValueError, match=r"one weight vector \[2\], got shape \(2, 2\)"):
        env.transform.set_next_preference([[1.0, 0.0], [0.0, 1.0]])
    assert env.transform._first is None  # nothing pending after a refusal
    with pytest.raises(ValueError, match="mode='given' takes each preference from the reset TensorDict"):
        make(2, mode="given").transform.set_next_preference([1.0, 0.0])
