"""MO-LavaGrid: maps, dynamics, rewards, domain randomization, specs and bad input (SPEC section 1.3)."""

import numpy as np
import pytest
import torch
from tensordict import TensorDict
from torchrl.envs.utils import check_env_specs

from morl_trl.envs import context_space, domain_of, evaluation_suite, make_env
from morl_trl.envs.lava_grid import (
    LAVA_GRID_CONTEXT,
    MOLavaGridEnv,
    evaluation_maps,
    format_lava_map,
    lava_grid_context,
    parse_lava_map,
)
from morl_trl.envs.lava_grid.context import _draw_lava_cells

LEFT, RIGHT, FWD = 0, 1, 2
OPEN = [[0] * 9 for _ in range(9)]

# SPEC 1.3, written out independently of the package's data file
SPEC_MAPS = {
    "Room": dict(
        goals=[(9, 9), (3, 3), (9, 3)], w=[0.5, 0.3, 0.2], agent=(6, 6, 3), n_lava=23,
        rows=".....L... .1.L.L.2. ...L.L... .LLL.LLL. ....^L... L.LL.L.LL ...L..... ...L.L.0. ...L.L...",
    ),
    "CheckerBoard": dict(
        goals=[(9, 3), (9, 9), (3, 9)], w=[0.3, 0.1, 0.6], agent=(6, 4, 1), n_lava=40,
        rows=".L.L.L.L. L.L.L.L0L .L.LvL.L. L.L.L.L.L .L.L.L.L. L.L.L.L.L .L.L.L.L. L2L.L.L1L .L.L.L.L.",
    ),
    "Corridor": dict(goals=[(6, 7), (4, 5), (8, 5)], w=[0.6, 0.1, 0.3], agent=(2, 6, 0), n_lava=31, rows=None),
    "Islands": dict(goals=[(9, 3), (10, 10), (3, 9)], w=[1 / 3] * 3, agent=(2, 3, 0), n_lava=39, rows=None),
    "Maze": dict(goals=[(10, 2), (2, 10), (10, 10)], w=[0.05, 0.05, 0.9], agent=(2, 2, 0), n_lava=32, rows=None),
    "Snake": dict(goals=[(7, 10), (8, 2), (10, 10)], w=[0.2, 0.3, 0.5], agent=(2, 2, 0), n_lava=32, rows=None),
    "Labyrinth": dict(goals=[(6, 6), (8, 8), (10, 10)], w=[0.5, 0.05, 0.45], agent=(2, 10, 0), n_lava=32, rows=None),
    "Smiley": dict(goals=[(5, 3), (8, 3), (6, 7)], w=[0.4, 0.4, 0.2], agent=(2, 10, 0), n_lava=21, rows=None),
}


def run(env, actions):
    """Step sub-env batch with a [T] (or [T, N]) action list; return rewards [T, N, 2] and the last TensorDict."""
    td = env.reset()
    rewards, tds = [], []
    for a in actions:
        td["action"] = torch.as_tensor(a).expand(env.num_envs).to(env.device)
        out = env.step(td)
        rewards.append(out["next", "reward"])
        tds.append(out["next"])
        td = out["next"]
    return torch.stack(rewards), tds


def expected_observation(rows: str, goals, weights, agent):
    """Decode a SPEC map by hand: [dir, w, C] with C[(x-1)*11 + (y-1)] MiniGrid colour indices."""
    colour = np.full((11, 11), 0.0)  # [x-1, y-1]
    colour[0, :] = colour[10, :] = colour[:, 0] = colour[:, 10] = 5  # lava ring
    for j, row in enumerate(rows.split()):
        for i, ch in enumerate(row):
            if ch == "L":
                colour[i + 1, j + 1] = 5
    for (x, y), c in zip(goals, (1, 4, 2)):  # green, yellow, blue
        colour[x - 1, y - 1] = c
    colour[agent[0] - 1, agent[1] - 1] = 3  # purple agent on top
    return torch.tensor([agent[2], *weights, *colour.reshape(-1)], dtype=torch.float32)


# ---------------------------------------------------------------------------- registry and maps
def test_ids_suite_and_domain_facts():
    suite = evaluation_suite("MOLavaGridDR-v0")
    assert suite == [f"MOLavaGrid{n}-v0" for n in
                     ("CheckerBoard", "Smiley", "Snake", "Islands", "Labyrinth", "Maze", "Corridor", "Room")]
    spec = domain_of("MOLavaGridDR-v0")
    assert spec.gamma == 0.995 and spec.hv_ref_point == (-1000.0, -500.0)
    assert spec.objective_names == ("lava", "time") and spec.max_episode_steps == 256
    assert context_space("MOLavaGridRoom-v0").dim == 93


@pytest.mark.parametrize("name", sorted(SPEC_MAPS))
def test_evaluation_maps_match_spec(name):
    facts = SPEC_MAPS[name]
    ctx = evaluation_maps()[name]
    assert ctx[81:87].reshape(3, 2).tolist() == [list(map(float, g)) for g in facts["goals"]]
    torch.testing.assert_close(ctx[87:90], torch.tensor(facts["w"]))
    assert ctx[90:].tolist() == list(map(float, facts["agent"]))
    assert int(ctx[:81].sum()) == facts["n_lava"]
    assert torch.equal(parse_lava_map(format_lava_map(ctx), ctx[87:90].tolist()), ctx)  # text round trip


@pytest.mark.parametrize("name", ["Room", "CheckerBoard"])
def test_initial_observation_is_the_decoded_map(name):
    facts = SPEC_MAPS[name]
    obs = make_env(f"MOLavaGrid{name}-v0").reset()["observation"][0]
    expected = expected_observation(facts["rows"], facts["goals"], facts["w"], facts["agent"])
    assert obs.shape == (125,)
    torch.testing.assert_close(obs, expected, rtol=0, atol=1e-7)


# ---------------------------------------------------------------------------- hand-worked dynamics
def test_snake_full_episode_exact_rewards_and_termination():
    # (2,2) E: lava (3,2), three empty cells, lava (7,2), goal 1 at (8,2) [w .3]; on to (10,2),
    # turn south, down x=10 to goal 2 at (10,10) [w .5]; turn west, lava (9,10), (8,10), goal 0 (7,10) [w .2]
    actions = [FWD] * 8 + [RIGHT] + [FWD] * 8 + [RIGHT] + [FWD] * 3
    env = make_env("MOLavaGridSnake-v0")
    rewards, tds = run(env, actions)
    expected = [[0.0, -3.0]] * 21
    expected[0] = expected[4] = expected[18] = [-20.0, -3.0]
    expected[5], expected[16], expected[20] = [90.0, 87.0], [150.0, 147.0], [60.0, 57.0]
    torch.testing.assert_close(rewards[:, 0], torch.tensor(expected), rtol=0, atol=1e-5)
    assert [bool(td["terminated"]) for td in tds] == [False] * 20 + [True]
    assert not any(bool(td["truncated"]) for td in tds)
    original = torch.stack([td["original_reward"][0, 0] for td in tds])
    torch.testing.assert_close(original, 0.9 * rewards[:, 0, 0] + 0.1 * rewards[:, 0, 1])
    # collected goal weights read 0: after goal 1 (step 6), goal 2 (step 17), goal 0 (step 21)
    torch.testing.assert_close(tds[5]["observation"][0, 1:4], torch.tensor([0.2, 0.0, 0.5]))
    torch.testing.assert_close(tds[16]["observation"][0, 1:4], torch.tensor([0.2, 0.0, 0.0]))
    torch.testing.assert_close(tds[20]["observation"][0, 1:4], torch.zeros(3))
    # the collected goal-1 tile (8,2) stays yellow (4) once the agent has moved on
    assert tds[7]["observation"][0, 4 + 7 * 11 + 1] == 4.0
    assert tds[7]["observation"][0, 4 + 9 * 11 + 1] == 3.0  # the agent at (10, 2)


def test_room_lava_entry_turn_in_lava_and_exit():
    # (6,6) N: up to (6,3), turn east, into lava (7,3), turn in lava twice, on to (8,3), goal 2 (9,3)
    actions = [FWD, FWD, FWD, RIGHT, FWD, LEFT, RIGHT, FWD, FWD]
    rewards, tds = run(make_env("MOLavaGridRoom-v0"), actions)
    expected = torch.tensor([[0, -3], [0, -3], [0, -3], [0, -3], [-20, -3], [-20, -3], [-20, -3], [0, -3], [60, 57]],
                            dtype=torch.float32)
    torch.testing.assert_close(rewards[:, 0], expected, rtol=0, atol=1e-5)
    assert tds[-1]["observation"][0, :4].tolist() == pytest.approx([0.0, 0.5, 0.3, 0.0])


def test_forward_from_lava_into_wall_is_not_penalized():
    # Maze (2,2) E: turn north, into the ring lava (2,1), bump the wall twice, turn while on the ring
    actions = [LEFT, FWD, FWD, FWD, RIGHT, FWD]
    rewards, tds = run(make_env("MOLavaGridMaze-v0"), actions)
    expected = torch.tensor([[0, -3], [-20, -3], [0, -3], [0, -3], [-20, -3], [-20, -3]], dtype=torch.float32)
    torch.testing.assert_close(rewards[:, 0], expected)
    # after the bumps the agent is still at (2,1): obs column 4 + (2-1)*11 + (1-1)
    assert tds[3]["observation"][0, 4 + 11] == 3.0
    # the last forward (east, from (2,1)) moves along the ring into lava (3,1)
    assert tds[5]["observation"][0, 4 + 22] == 3.0


def test_goal_on_the_ring_and_revisiting_a_collected_goal():
    ctx = lava_grid_context(OPEN, [(1, 5), (4, 5), (5, 5)], [0.5, 0.25, 0.25], agent_pos=(3, 5), agent_dir=2)
    env = MOLavaGridEnv(context=ctx)
    obs = env.reset()["observation"][0]
    assert obs[4 + 0 * 11 + 4] == 1.0  # goal 0 replaces the ring lava at (1,5): green
    # west: (2,5) empty, goal 0 on the ring; turn around (not in lava: no penalty); back east twice, goals 1, 2
    rewards, tds = run(env, [FWD, FWD, RIGHT, RIGHT, FWD, FWD, FWD, FWD])
    expected = torch.tensor([[0, -3], [150, 147], [0, -3], [0, -3], [0, -3], [0, -3], [75, 72], [75, 72]],
                            dtype=torch.float32)
    torch.testing.assert_close(rewards[:, 0], expected)
    assert bool(tds[-1]["terminated"]) and not bool(tds[-2]["terminated"])


def test_terminates_after_third_goal_and_truncates_at_256():
    ctx = lava_grid_context(OPEN, [(6, 5), (7, 5), (8, 5)], [0.5, 0.25, 0.25], agent_pos=(5, 5), agent_dir=0)
    rewards, tds = run(MOLavaGridEnv(context=ctx), [FWD] * 3)
    torch.testing.assert_close(rewards[:, 0], torch.tensor([[150.0, 147.0], [75.0, 72.0], [75.0, 72.0]]))
    assert [bool(t["terminated"]) for t in tds] == [False, False, True]

    env = make_env("MOLavaGridRoom-v0", num_envs=2)
    rewards, tds = run(env, [LEFT] * 256)
    assert torch.equal(rewards, torch.tensor([0.0, -3.0]).expand(256, 2, 2))
    truncated = torch.stack([t["truncated"].squeeze(-1) for t in tds])
    assert not truncated[:255].any() and truncated[255].all()
    assert torch.equal(tds[255]["done"], tds[255]["truncated"]) and not tds[255]["terminated"].any()


# ---------------------------------------------------------------------------- domain randomization
def test_dr_sampler_distribution_properties():
    n = 20_000
    gen = torch.Generator().manual_seed(0)
    ctx = LAVA_GRID_CONTEXT.sample(n, generator=gen)
    LAVA_GRID_CONTEXT.validate(ctx, check_range=True)
    goals = ctx[:, 81:87].reshape(n, 3, 2)
    agent = ctx[:, 90:92]
    assert not (goals == agent[:, None]).all(-1).any()  # never on the agent
    g = goals[:, :, 0] * 13 + goals[:, :, 1]
    assert (g[:, 0] != g[:, 1]).all() and (g[:, 0] != g[:, 2]).all() and (g[:, 1] != g[:, 2]).all()
    # start and goals cover the whole 11x11, ring included; four directions
    assert torch.unique(agent[:, 0] * 13 + agent[:, 1]).numel() == 121
    assert torch.unique(g).numel() == 121
    assert set(ctx[:, 92].unique().tolist()) == {0.0, 1.0, 2.0, 3.0}
    torch.testing.assert_close(ctx[:, 87:90].sum(1), torch.ones(n))
    # layout lava: k ~ U{0..59} on the 117 free cells, so E[interior] = 29.5 * (free interior cells) / 117
    interior = ctx[:, :81].sum(1)
    assert interior.min() == 0 and interior.max() <= 59
    occupied = (((goals >= 2) & (goals <= 10)).all(-1)).sum(1) + ((agent >= 2) & (agent <= 10)).all(-1)
    expected_mean = (29.5 * (81 - occupied) / 117).float().mean()
    assert abs(interior.mean() - expected_mean) < 0.3  # the s.e. of the mean is ~0.1


def test_dr_lava_count_is_0_to_59_on_free_cells():
    n = 20_000
    gen = torch.Generator().manual_seed(1)
    taken = torch.stack([torch.randperm(121, generator=gen)[:4] for _ in range(200)]).repeat(100, 1)
    lava, k = _draw_lava_cells(taken, gen)
    assert torch.equal(lava.sum(1), k)
    assert k.min() == 0 and k.max() == 59  # randint(0, 60): the upper bound is exclusive
    assert not lava.gather(1, taken).any()
    assert lava.shape == (n, 121)


def test_dr_start_avoids_the_previous_goals():
    n = 20_000
    prev = evaluation_maps()["Room"].expand(n, 93)
    cells = {(9, 9), (3, 3), (9, 3)}
    ctx = LAVA_GRID_CONTEXT.sample(n, generator=torch.Generator().manual_seed(2), previous=prev)
    starts = {tuple(a) for a in ctx[:, 90:92].long().tolist()}
    assert not starts & cells and len(starts) == 118
    # without `previous` those cells are drawn too (the check above can fail)
    ctx = LAVA_GRID_CONTEXT.sample(n, generator=torch.Generator().manual_seed(2))
    assert cells <= {tuple(a) for a in ctx[:, 90:92].long().tolist()}


def test_dr_env_is_seeded_and_randomizes_per_subenv_and_reset():
    def contexts(seed):
        env = make_env("MOLavaGridDR-v0", num_envs=8, seed=seed)
        first = env.reset()["context"]
        return first, env.reset()["context"]

    a1, a2 = contexts(3)
    b1, b2 = contexts(3)
    assert torch.equal(a1, b1) and torch.equal(a2, b2)
    assert not torch.equal(a1, a2)
    assert torch.unique(a1, dim=0).shape[0] == 8


def test_dr_transform_start_avoids_the_previous_goals():
    # DomainRandomization passes the ending episodes' contexts as `previous` (the agreed interface)
    env = make_env("MOLavaGridDR-v0", num_envs=4096, seed=4)
    first = env.reset()["context"]
    second = env.reset()["context"]
    on_previous_goal = (first[:, 81:87].reshape(-1, 3, 2) == second[:, None, 90:92]).all(-1).any(1)
    assert not on_previous_goal.any()  # ~100 of 4096 would be without the exclusion


def test_in_env_randomization_partial_reset():
    env = MOLavaGridEnv(num_envs=4, randomize=True, seed=0)
    td = env.reset()
    before = td["context"].clone()
    # TorchRL's partial reset: the TensorDict carries the current state, "_reset" marks who restarts
    td["_reset"] = torch.tensor([[True], [False], [True], [False]])
    after = env.reset(td)["context"]
    assert torch.equal(after[1], before[1]) and torch.equal(after[3], before[3])
    assert not torch.equal(after[0], before[0]) and not torch.equal(after[2], before[2])
    for i in (0, 2):  # the new start avoids the previous goals
        start = after[i, 90:92]
        assert not (before[i, 81:87].reshape(3, 2) == start).all(-1).any()
    env2 = MOLavaGridEnv(num_envs=4, randomize=True, seed=0)
    assert torch.equal(env2.reset()["context"], before)


# ---------------------------------------------------------------------------- TorchRL contract
@pytest.mark.parametrize("num_envs", [1, 1024])
@pytest.mark.parametrize("env_id", ["MOLavaGridRoom-v0", "MOLavaGridDR-v0"])
def test_check_env_specs(env_id, num_envs):
    check_env_specs(make_env(env_id, num_envs=num_envs, seed=0))


def test_partial_reset_and_setting_a_layout_at_reset():
    env = make_env("MOLavaGridRoom-v0", num_envs=3)
    _, tds = run(env, [FWD, FWD])  # all three at (6,4)
    maze = evaluation_maps()["Maze"]
    td = tds[-1].clone()
    td["_reset"] = torch.tensor([[True], [False], [False]])
    td["context"][0] = maze
    td = env.reset(td)
    obs = td["observation"]
    assert obs[0, 4 + 1 * 11 + 1] == 3.0  # sub-env 0: Maze start (2,2)
    assert obs[1, 4 + 5 * 11 + 3] == 3.0 and obs[2, 4 + 5 * 11 + 3] == 3.0  # others still at (6,4)
    assert torch.equal(env.context[0], maze)
    td["_reset"] = torch.tensor([[False], [True], [False]])
    td = env.reset(td)
    assert td["observation"][1, 4 + 5 * 11 + 5] == 3.0  # sub-env 1 back at Room's (6,6)
    assert td["observation"][2, 4 + 5 * 11 + 3] == 3.0


def test_render_rgb():
    env = make_env("MOLavaGridRoom-v0", num_envs=2)
    img = env.render(1, tile_size=8)
    assert img.shape == (104, 104, 3) and img.dtype == np.uint8
    assert img[2 * 8 + 4, 7 * 8 + 4].tolist() == [255, 128, 0]  # lava at (7,2): row y, column x
    assert img[9 * 8 + 4, 9 * 8 + 4].tolist() == [0, 255, 0]  # goal 0 at (9,9)
    assert img[3 * 8 + 4, 3 * 8 + 4].tolist() == [255, 255, 0]  # goal 1 at (3,3)
    assert img[6 * 8 + 4, 6 * 8 + 4].tolist() == [255, 0, 0]  # the agent at (6,6)
    assert img[0 * 8 + 4, 0 * 8 + 4].tolist() == [100, 100, 100]  # wall
    with pytest.raises(ValueError, match="out of range"):
        env.render(2)


# ---------------------------------------------------------------------------- bad input
def _bad_contexts():
    room = evaluation_maps()["Room"]

    def edit(**kw):
        c = room.clone()
        for k, v in kw.items():
            c[LAVA_GRID_CONTEXT.index(k)] = v
        return c

    return {
        "goal on lava": (edit(goal0_x=7, goal0_y=2), "interior lava"),
        "goal outside": (edit(goal1_x=12), "1..11"),
        "goal at 0": (edit(goal1_y=0), "1..11"),
        "goals coincide": (edit(goal1_x=9, goal1_y=9), "different cells"),
        "negative weight": (edit(weight0=-0.1, weight1=0.9), "non-negative"),
        "weights sum": (edit(weight0=0.6), "sum to 1"),
        "agent on goal": (edit(agent_x=9, agent_y=9), "agent cannot start on a goal"),
        "direction": (edit(agent_dir=4), "agent_dir"),
        "fractional cell": (edit(agent_x=2.5), "integers"),
        "lava bit": (edit(lava_x2_y2=0.5), "0 or 1"),
        "nan": (edit(weight2=float("nan")), "finite"),
        "width": (room[:81], r"expected \[..., 93\]"),
    }


@pytest.mark.parametrize("case", list(_bad_contexts()))
def test_bad_context_raises_and_leaves_env_unchanged(case):
    bad, message = _bad_contexts()[case]
    env = make_env("MOLavaGridRoom-v0", num_envs=2)
    td = env.reset()
    td["action"] = torch.tensor([FWD, RIGHT])
    env.step(td)
    ctx_before, state_before = env.context, env._cells.clone()
    pos_before = env._pos.clone()
    with pytest.raises(ValueError, match=message):
        env.reset(TensorDict({"context": bad.expand(2, *bad.shape)}, [2]))
    assert torch.equal(env.context, ctx_before) and torch.equal(env._cells, state_before)
    assert torch.equal(env._pos, pos_before)
    with pytest.raises(ValueError, match=message):
        MOLavaGridEnv(context=bad)


def test_bad_helper_input():
    with pytest.raises(ValueError, match=r"layout has shape \(8, 9\)"):
        lava_grid_context(OPEN[:8], [(2, 3), (4, 5), (6, 7)], [0.2, 0.3, 0.5])
    with pytest.raises(ValueError, match="goals must be 3"):
        lava_grid_context(OPEN, [(2, 3), (4, 5)], [0.2, 0.3, 0.5])
    with pytest.raises(ValueError, match="sum to 1"):
        lava_grid_context(OPEN, [(2, 3), (4, 5), (6, 7)], [0.2, 0.3, 0.6])
    with pytest.raises(ValueError, match="unknown map cell 'X'"):
        parse_lava_map(["X" + "." * 8] + ["." * 9] * 8, [0.2, 0.3, 0.5])
    with pytest.raises(ValueError, match="out of the action space"):
        env = make_env("MOLavaGridRoom-v0")
        td = env.reset()
        td["action"] = torch.tensor([3])
        env.step(td)


# ---------------------------------------------------------------------------- devices
@pytest.mark.skipif(not torch.cuda.is_available(), reason="no CUDA device")
def test_cuda_matches_cpu():
    actions = torch.randint(0, 3, (300, 64), generator=torch.Generator().manual_seed(0))
    out = {}
    for device in ("cpu", "cuda"):
        env = make_env("MOLavaGridDR-v0", num_envs=64, seed=5, device=device)
        td = env.reset()
        rewards = []
        for a in actions:
            td["action"] = a.to(device)
            td, nxt = env.step_and_maybe_reset(td)
            rewards.append(td["next", "reward"].cpu())
            td = nxt
        out[device] = (torch.stack(rewards), env.context.cpu())
    assert torch.equal(out["cpu"][0], out["cuda"][0]) and torch.equal(out["cpu"][1], out["cuda"][1])
