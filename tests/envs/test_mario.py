"""MO-SuperMarioBros: stages as contexts, the NES game logic, frames, rewards, registry."""

from __future__ import annotations

import importlib.util
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import torch
from tensordict import TensorDict
from torchrl.envs import TransformedEnv
from torchrl.envs.utils import check_env_specs

from morl_trl.envs import ContextualMOEnv, domain_of, evaluation_suite, list_envs, make_env
from morl_trl.envs.mario.frames import AreaResize, FramePipeline, area_weights
from morl_trl.envs.mario.stages import (
    EVAL_STAGES,
    MARIO_STAGE_SPACE,
    STAGES,
    TRAIN_STAGES,
    MarioStageSpace,
    parse_stage,
)
from morl_trl.transforms.domain_randomization import DomainRandomization

HAS_NES = importlib.util.find_spec("nes_py") is not None and importlib.util.find_spec("gym_super_mario_bros") is not None
needs_nes = pytest.mark.skipif(not HAS_NES, reason="needs the mario extra (nes-py, gym-super-mario-bros)")
NOOP, RIGHT, RIGHT_A, RIGHT_B, RIGHT_A_B, JUMP, LEFT = range(7)
ROOT = Path(__file__).resolve().parents[2]


# ---------------------------------------------------------------------------- stages, registry
def test_stage_tables():
    assert len(STAGES) == 32 and len(TRAIN_STAGES) == 31
    assert (3, 3) in STAGES and (3, 3) not in TRAIN_STAGES
    assert EVAL_STAGES == ((1, 2), (3, 2), (3, 3), (4, 3), (5, 2), (5, 3), (7, 3), (8, 1))
    assert parse_stage("7-3") == (7, 3)


@pytest.mark.parametrize("bad", ["3-5", "9-1", "0-1", "1_1", "x"])
def test_unknown_stage_name_lists_valid_ones(bad):
    with pytest.raises(ValueError, match=r"unknown stage .*valid stages: 1-1, 1-2.*8-4"):
        parse_stage(bad)


@pytest.mark.parametrize("bad", [[3.5, 1.0], [9.0, 1.0], [1.0, 0.0], [2.0, 5.0], [float("nan"), 1.0]])
def test_space_rejects_non_stages(bad):
    with pytest.raises(ValueError, match="valid stages|finite"):
        MARIO_STAGE_SPACE.validate(torch.tensor(bad))
    with pytest.raises(ValueError):
        MARIO_STAGE_SPACE.validate(torch.tensor([[1.0, 1.0], bad]))


def test_space_sampling_is_uniform_over_training_stages_and_reproducible():
    g = torch.Generator().manual_seed(0)
    ctx = MARIO_STAGE_SPACE.sample(31_000, generator=g)
    assert ctx.shape == (31_000, 2) and ctx.dtype == torch.float32
    MARIO_STAGE_SPACE.validate(ctx, check_range=True)
    drawn, counts = torch.unique(ctx, dim=0, return_counts=True)
    assert [tuple(map(int, s)) for s in drawn.tolist()] == list(TRAIN_STAGES)  # never 3-3
    assert counts.min() > 850 and counts.max() < 1150  # 1000 expected each
    again = MARIO_STAGE_SPACE.sample(50, generator=torch.Generator().manual_seed(0))
    assert torch.equal(again, ctx[:50])


def test_space_with_other_training_stages():
    space = MarioStageSpace(train_stages=((1, 1), (8, 4)))
    ctx = space.sample(200, generator=torch.Generator().manual_seed(1))
    assert set(map(tuple, ctx.long().tolist())) == {(1, 1), (8, 4)}
    with pytest.raises(ValueError, match="train_stages"):
        MarioStageSpace(train_stages=((9, 9),))


def test_registry_ids_and_suite():
    ids = set(list_envs())
    assert "MOSuperMarioBrosZeroShot-v2" in ids
    assert {f"MOSuperMarioBros-{w}-{l}-v2" for w, l in STAGES} <= ids
    assert evaluation_suite("MOSuperMarioBrosZeroShot-v2") == [
        f"MOSuperMarioBros-{s}-v2" for s in ("1-2", "3-2", "3-3", "4-3", "5-2", "5-3", "7-3", "8-1")
    ]
    spec = domain_of("MOSuperMarioBros-3-3-v2")
    assert spec.objective_names == ("x_pos", "coin", "enemy")
    assert spec.hv_ref_point == (-100.0, -100.0, -100.0) and spec.gamma == 0.99
    assert spec.max_episode_steps == 500
    assert spec.context_of("MOSuperMarioBros-3-3-v2").tolist() == [3.0, 3.0]
    with pytest.raises(ValueError, match="unknown env id"):
        make_env("MOSuperMarioBros-9-1-v2")


class _StageEcho(ContextualMOEnv):
    """No emulator: observes its context; lets DR be reset thousands of times quickly."""

    objective_names = ("x_pos", "coin", "enemy")

    def __init__(self, num_envs=1):
        super().__init__(context_space=MARIO_STAGE_SPACE, num_envs=num_envs, seed=0, max_episode_steps=2)

    def _domain_observation_spec(self):
        from torchrl.data import Unbounded

        return {"observation": Unbounded(shape=(2,))}

    def _domain_action_spec(self):
        from torchrl.data import Categorical

        return Categorical(7, shape=())

    def _reset_subenvs(self, idx, context):
        pass

    def _observe(self):
        return {"observation": self._context.clone()}

    def _step_subenvs(self, action):
        zeros = torch.zeros(self.num_envs, 3)
        return self._observe(), zeros, zeros[:, :1], torch.zeros(self.num_envs, dtype=torch.bool)


def test_domain_randomization_never_draws_held_out_stage():
    env = TransformedEnv(_StageEcho(num_envs=8), DomainRandomization(MARIO_STAGE_SPACE, seed=3))
    seen = torch.cat([env.reset()["context"] for _ in range(500)])  # 4000 draws
    stages = set(map(tuple, seen.long().tolist()))
    assert (3, 3) not in stages
    assert stages == set(TRAIN_STAGES)


# ---------------------------------------------------------------------------- frame pipeline
@pytest.mark.parametrize("src,dst,up,block", [(240, 84, 7, 20), (256, 84, 21, 64), (6, 3, 1, 2)])
def test_area_weights_match_replicate_then_block_mean(src, dst, up, block):
    # area averaging = replicate each source sample `up` times, then average blocks of `block`
    x = torch.rand(src, dtype=torch.float64)
    expected = x.repeat_interleave(up).reshape(dst, block).mean(1)
    assert up * src == block * dst
    torch.testing.assert_close(area_weights(src, dst) @ x, expected)


def test_area_resize_2d():
    img = torch.rand(3, 240, 256) * 255
    rows = img.double().repeat_interleave(7, -2).reshape(3, 84, 20, 256).mean(2)
    expected = rows.repeat_interleave(21, -1).reshape(3, 84, 84, 64).mean(3)
    torch.testing.assert_close(AreaResize((240, 256), (84, 84))(img).double(), expected, atol=1e-3, rtol=0)


def test_frame_pipeline_maxpool_gray_and_dtype():
    pipe = FramePipeline((240, 256), (84, 84), rgb_channels=(2, 1, 0))  # B, G, R, x like the NES core
    frames = torch.zeros(3, 2, 240, 256, 4, dtype=torch.uint8)
    frames[0, 0, ..., 2] = 255  # pure red in the older frame only
    frames[1, 1, ..., 1] = 255  # pure green in the newer frame only
    frames[2, 0, ..., :3] = 255  # white
    frames[2, 1, ..., 0] = 255  # + blue: the max stays white
    frames[..., 3] = 77  # the padding byte is ignored
    out = pipe(frames)
    assert out.shape == (3, 84, 84) and out.dtype == torch.uint8
    assert out[0].unique().tolist() == [54]  # int(0.2125 * 255)
    assert out[1].unique().tolist() == [182]  # int(0.7154 * 255)
    assert out[2].unique().tolist() == [255]
    with pytest.raises(ValueError, match=r"\[B, 2, H, W, C\]"):
        pipe(frames[:, 0])


# ---------------------------------------------------------------------------- NumPy 2 shim
def test_rom_header_and_ram_reads_use_ints():
    pytest.importorskip("numpy", minversion="2")
    if not HAS_NES:
        pytest.skip("needs the mario extra")
    from morl_trl.envs.mario._nes import read_rom_header, rom_path
    from morl_trl.envs.mario.game import read_bcd, x_position

    header = np.fromfile(rom_path("pixel"), dtype=np.uint8)[:16]
    with pytest.raises(OverflowError):  # nes-py's expression, on NumPy 2
        _ = 16 * header[4] * 2**10
    info = read_rom_header(rom_path("pixel"))
    assert (info.prg_rom_kb, info.chr_rom_kb, info.mapper, info.has_trainer, info.is_pal) == (32, 8, 0, False, False)
    assert info.prg_rom_bytes == 32768

    ram = np.zeros(0x800, dtype=np.uint8)
    ram[0x6D], ram[0x86] = 3, 200
    with pytest.raises(OverflowError):  # gym-super-mario-bros' _x_position, on NumPy 2
        _ = ram[0x6D] * 0x100 + ram[0x86]
    assert x_position(ram) == 968
    ram[0x7DE:0x7E4] = [0, 1, 2, 3, 5, 0]
    assert read_bcd(ram, 0x7DE, 6) == 12350


@pytest.mark.mario
@needs_nes
def test_upstream_shim_gives_int_header_sizes():
    from morl_trl.envs.mario._compat import numpy2_shim

    sdl_before = os.environ.get("SDL_AUDIODRIVER")
    numpy2_shim()
    assert os.environ.get("SDL_AUDIODRIVER") == sdl_before  # gym's import side effect undone
    from nes_py._rom import ROM

    from morl_trl.envs.mario._nes import rom_path

    rom = ROM(rom_path("pixel"))
    assert (rom.prg_rom_size, rom.chr_rom_size) == (32, 8)
    assert rom.prg_rom_stop == 16 + 32 * 1024 and rom.chr_rom_stop == 16 + 40 * 1024


def test_domain_imports_neither_gym_nor_nes_py():
    code = (
        "import sys\n"
        "from morl_trl.envs import make_env, list_envs\n"
        "list_envs()\n"
        "import morl_trl.envs.mario\n"
        "assert 'gym' not in sys.modules and 'nes_py' not in sys.modules, 'imported at import'\n"
    )
    if HAS_NES:
        code += (
            "env = make_env('MOSuperMarioBros-1-1-v2', num_envs=1)\n"
            "env.rollout(2)\n"
            "assert 'gym' not in sys.modules and 'nes_py' not in sys.modules, 'imported when used'\n"
        )
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT, timeout=600)  # (a hang guard)
    assert proc.returncode == 0, proc.stderr
    assert "Gym has been unmaintained" not in proc.stderr + proc.stdout


# ---------------------------------------------------------------------------- the game

@pytest.mark.mario
@needs_nes
def test_every_stage_loads_and_steps():
    # first of the emulator tests: it leaves one started emulator of every stage in the
    # process-wide pool, which the tests below take instead of starting their own
    from morl_trl.envs.mario import MOSuperMarioBrosEnv, StagePool

    pool = StagePool.shared()
    env = MOSuperMarioBrosEnv(num_envs=32)
    assert env.stage_pool is pool
    stages = TensorDict(context=torch.tensor(STAGES, dtype=torch.float32), batch_size=[32])
    started = pool.started
    env.reset(stages)
    assert [g.loaded_stage() for g in env._games] == list(STAGES)  # the RAM says so
    assert env.stage_names()[10] == "3-3"
    assert pool.started - started <= 32
    started = pool.started
    td = env.reset(stages)
    assert pool.started == started  # a reset restores, it starts nothing new
    first = td["observation"]
    assert first.shape == (32, 4, 84, 84) and first.dtype == torch.uint8
    assert torch.equal(first[:, 0], first[:, 3])  # the stack starts as 4 copies
    assert len({bytes(f[0].numpy()) for f in first}) > 20  # the stages look different
    td["action"] = torch.full((32,), RIGHT)
    out = env.step(td)["next"]
    assert not out["done"].any()
    assert out["observation"].shape == (32, 4, 84, 84)
    assert torch.isfinite(out["reward"]).all() and (out["reward"][:, 0] > 0).all()  # free start x
    idle = pool.idle()
    env.close()
    assert pool.idle() == idle + 32  # given back, not destroyed


@pytest.mark.mario
@needs_nes
def test_first_steps_have_the_reference_rewards():
    env = make_env("MOSuperMarioBros-1-1-v2", num_envs=1)
    env.reset()
    td = env.rollout(7, policy=lambda td: td.set("action", torch.tensor([NOOP])))
    reward = td["next", "reward"][0]
    # step 1: x jumps from the reference's 0 to the start x = 40 -> 40 * 0.03; nothing else
    torch.testing.assert_close(reward[0], torch.tensor([1.2, 0.0, 0.0]))
    assert td["next", "original_reward"][0, 0].item() == 40.0
    # standing still, the clock ticks (-1) once within the next 24 frames: -0.03 on every objective
    torch.testing.assert_close(reward[1:].sum(0), torch.tensor([-0.03, -0.03, -0.03]))
    assert td["next", "original_reward"][0, 1:].sum().item() == -1.0
    obs = td["next", "observation"][0]
    assert torch.equal(obs[1, :3], obs[0, 1:])  # the stack shifts by one frame per step
    env.close()


@pytest.mark.mario
@needs_nes
def test_run_right_and_jump_on_1_1_ends_by_flag_or_death():
    env = make_env("MOSuperMarioBros-1-1-v2", num_envs=1)

    def policy(td):
        t = policy.t = getattr(policy, "t", -1) + 1
        return td.set("action", torch.tensor([RIGHT_A_B if t % 12 < 9 else RIGHT_B]))  # release A to re-jump

    td = env.rollout(500, policy=policy)
    steps = td.shape[-1]
    assert steps < 500 and td["next", "terminated"][0, -1].item() and not td["next", "truncated"].any()
    ret = td["next", "reward"][0].sum(0)
    game = env._games[0]
    assert ret[0] > 3.0  # more than 100 pixels of progress, net of penalties
    death = game.is_dying or game.is_dead
    assert death != game.flag_get
    # x objective = (final x - 0 + time) * 0.03, up to float rounding (no death penalty, as the authors')
    clock = game.time - 400
    expected = (game.x + clock) * 0.03
    assert abs(ret[0].item() - expected) < 1e-3
    # a terminated sub-env stepped again stays put: no reward, still terminated
    last = td[..., -1]["next"].clone()
    again = env.step(last.set("action", torch.tensor([RIGHT])))["next"]
    assert again["terminated"].all() and (again["reward"] == 0).all()
    assert torch.equal(again["observation"], last["observation"])
    env.close()


@pytest.mark.mario
@needs_nes
def test_game_logic_matches_upstream_frame_by_frame():
    from morl_trl.envs.mario._compat import upstream_stage_env
    from morl_trl.envs.mario.game import SIMPLE_MOVEMENT_BUTTONS, MarioStage

    upstream, ours = upstream_stage_env(1, 1), MarioStage(1, 1)
    screen = upstream.reset()
    assert np.array_equal(screen, ours.nes.rgb())
    pattern = [RIGHT_A_B] * 10 + [RIGHT_B] * 4 + [RIGHT] * 6 + [JUMP] * 3 + [NOOP]
    for frame in range(600):
        buttons = SIMPLE_MOVEMENT_BUTTONS[pattern[frame % len(pattern)]]
        screen, _, done, info = upstream.step(buttons)
        out = ours.frame(buttons)
        assert np.array_equal(screen, ours.nes.rgb()), frame
        assert (info["x_pos"], info["time"], info["coins"], info["score"], info["flag_get"]) == (
            ours.x, ours.time, ours.coins, ours.score, out.flag), frame
        assert done == out.done, frame
        if done:
            break
    assert frame > 100  # a real stretch of play was compared
    upstream.close()
    ours.close()


@pytest.mark.mario
@needs_nes
def test_zero_shot_env_draws_training_stages_and_loads_them():
    env = make_env("MOSuperMarioBrosZeroShot-v2", num_envs=2, seed=5)
    for _ in range(2):
        ctx = env.reset()["context"]
        for i, stage in enumerate(map(tuple, ctx.long().tolist())):
            assert stage in TRAIN_STAGES
            assert env._games[i].loaded_stage() == stage
    check_env_specs(env)
    env.close()


@pytest.mark.mario
@needs_nes
def test_check_env_specs_and_bad_context_changes_nothing():
    env = make_env("MOSuperMarioBros-3-3-v2", num_envs=2)
    check_env_specs(env)
    assert env.context.tolist() == [[3.0, 3.0], [3.0, 3.0]]
    with pytest.raises(ValueError, match="valid stages"):
        env.reset(TensorDict(context=torch.tensor([[3.5, 1.0], [1.0, 1.0]]), batch_size=[2]))
    assert env.context.tolist() == [[3.0, 3.0], [3.0, 3.0]]
    with pytest.raises(ValueError, match="action"):
        env.step(TensorDict(action=torch.tensor([7, 0]), batch_size=[2]))
    env.close()


@pytest.mark.mario
@needs_nes
def test_threads_do_not_change_results():
    actions = torch.tensor([[RIGHT_A_B, RIGHT], [RIGHT_B, JUMP], [RIGHT_A_B, LEFT]] * 5)
    outs = []
    for threads in (1, 2):
        env = make_env("MOSuperMarioBros-1-1-v2", num_envs=2, num_threads=threads)
        it = iter(actions)
        outs.append(env.rollout(15, policy=lambda td: td.set("action", next(it)), break_when_any_done=False))
        env.close()
    torch.testing.assert_close(outs[0]["next", "reward"], outs[1]["next", "reward"], rtol=0, atol=0)
    assert torch.equal(outs[0]["next", "observation"], outs[1]["next", "observation"])
    assert not torch.equal(outs[0]["next", "observation"][0], outs[0]["next", "observation"][1])


@pytest.mark.mario
@needs_nes
def test_partial_reset_touches_only_the_selected_sub_env():
    from morl_trl.envs.mario import MOSuperMarioBrosEnv

    env = make_env("MOSuperMarioBros-1-1-v2", num_envs=2)
    assert type(env) is MOSuperMarioBrosEnv  # frames are skipped natively: no TorchRL FrameSkipTransform
    start = env.reset()["observation"]
    td = start
    for _ in range(5):
        td = env.step(TensorDict(action=torch.tensor([RIGHT, RIGHT]), batch_size=[2]))["next"]
    moved = td["observation"]
    assert not torch.equal(moved[0], start[0])
    # as in step_and_maybe_reset: the carried TensorDict holds the sub-envs that keep going
    reset = td.clone().update({"_reset": torch.tensor([[False], [True]]), "context": torch.tensor([[1.0, 1.0], [8.0, 4.0]])})
    out = env.reset(reset)
    assert torch.equal(out["observation"][0], moved[0])  # untouched
    assert env.stage_names() == ["1-1", "8-4"]
    assert env._games[1].loaded_stage() == (8, 4)
    assert torch.equal(out["observation"][1, 0], out["observation"][1, 3])  # a fresh stack
    after = env.step(out.set("action", torch.tensor([RIGHT, RIGHT])))["next"]["observation"]
    assert torch.equal(after[0, :3], moved[0, 1:])  # sub-env 0 went on where it was
    assert torch.equal(after[1, :3], out["observation"][1, 1:])  # sub-env 1 from its new start
    env.close()


def test_missing_emulator_is_an_import_error_naming_the_extra(monkeypatch):
    from morl_trl.envs.mario import _nes

    real = importlib.util.find_spec
    monkeypatch.setattr(_nes.importlib.util, "find_spec", lambda name, *a: None if name == "nes_py" else real(name, *a))
    with pytest.raises(ImportError, match=r"morl-trl\[mario\]"):
        _nes.require_emulator()


@pytest.mark.mario
@needs_nes
@pytest.mark.parametrize("death_penalty_on_dying", [False, True])
def test_walking_into_the_first_goomba_on_1_1_ends_the_episode_before_the_lives_counter_drops_without_death_penalty(
    death_penalty_on_dying,
):
    # holding "right" from the start of 1-1, Mario meets the first Goomba at x = 296 on agent step 40
    kwargs = {"death_penalty_on_dying": True} if death_penalty_on_dying else {}
    env = make_env("MOSuperMarioBros-1-1-v2", num_envs=1, **kwargs)
    td = env.rollout(500, policy=lambda td: td.set("action", torch.tensor([RIGHT])))
    game = env._games[0]
    assert td.shape[-1] == 40  # the episode ends on the frame Mario starts dying ...
    assert td["next", "terminated"][0, -1].item() and not td["next", "terminated"][0, :-1].any()
    assert not td["next", "truncated"].any()
    assert game.is_dying and not game.flag_get and game.x == 296
    assert game.lives == 2  # ... before the lives counter drops: the authors' "lives dropped" -25 never fires
    reward = td["next", "reward"][0]
    # the first step earns the start x = 40 (1.2 scaled); walking right: 7 pixels a step (0.21)
    torch.testing.assert_close(reward[0], torch.tensor([1.2, 0.0, 0.0]))
    torch.testing.assert_close(reward[36:39], torch.tensor([[0.21, 0.0, 0.0]] * 3))
    # the last step: dx 7, the clock ticks (-1); the authors pay no death penalty in the vector reward,
    # our option adds -25 to every objective (-0.75 scaled)
    last = torch.tensor([0.18, -0.03, -0.03]) + (-0.75 if death_penalty_on_dying else 0.0)
    torch.testing.assert_close(reward[39], last)
    # the scalar original_reward is gym-super-mario-bros' own, whose -25 fires on the dying frame: 7 - 1 - 25
    assert td["next", "original_reward"][0, 39].item() == -19.0
    env.close()
