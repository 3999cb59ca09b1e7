"""MO-LavaGrid as one batched, pure-tensor TorchRL environment (SPEC section 1.3).

All ``N`` grids live in a few ``[N, ...]`` tensors (cell types, agent cell and facing, collected
goals), and one ``step`` advances them all with gathers and ``where``s: no Python loop over
sub-environments, the same code on CPU and GPU.
"""

from __future__ import annotations

import numpy as np
import torch
from tensordict import TensorDictBase
from torchrl.data import Bounded, Categorical

from morl_trl.envs.base import ContextualMOEnv
from morl_trl.envs.sampler import ContextSampler
from morl_trl.envs.lava_grid.spec import SORL
from morl_trl.envs.lava_grid.context import (
    AGENT_DIR,
    AGENT_X,
    AGENT_Y,
    GOALS_SLICE,
    GRID_SIZE,
    INNER,
    LAVA_GRID_CONTEXT,
    LAVA_SLICE,
    NUM_GOALS,
    WEIGHTS_SLICE,
    LavaGridContextSpace,
)

__all__ = ["MOLavaGridEnv"]

# cell types of the 13x13 grid (internal codes; the observation uses MiniGrid colour indices)
EMPTY, WALL, LAVA, GOAL0 = 0, 1, 2, 3  # goals are GOAL0 + i
# MiniGrid colour indices seen in the observation: red 0 (empty), green 1, blue 2, purple 3
# (agent), yellow 4, grey 5 (lava). Goal 0 is green, goal 1 yellow, goal 2 blue.
_COLOUR_OF_CELL = (0.0, 0.0, 5.0, 1.0, 4.0, 2.0)
AGENT_COLOUR = 3.0
LAVA_PENALTY = -20.0
TIME_PENALTY = -3.0
GOAL_BONUS = 100.0 * NUM_GOALS  # 300 * w_i, added to both objectives
# the authors' single-objective reward (info["original_scalar_reward"]) for their SAC baseline
ORIGINAL_REWARD_WEIGHTS = SORL.weights  # (0.9, 0.1), written once in the domain's spec
OBS_SIZE = 1 + NUM_GOALS + INNER * INNER  # 125


class MOLavaGridEnv(ContextualMOEnv):
    """MO-LavaGrid: collect three weighted goals on a 13x13 grid, trading lava for time.

    Every sub-env is a 13x13 grid: walls on the border, a lava ring just inside, a 9x9 interior
    layout of lava, three goals and the agent, all given by its context (see
    :mod:`morl_trl.envs.lava_grid.context`). Actions: 0 turn left, 1 turn right, 2 forward.

    * ``observation`` ``[*B, 125]`` float32: ``[dir, w0, w1, w2, C]`` with ``C`` the 11x11
      playable cells x-major (``C[(x - 1) * 11 + (y - 1)]``) as MiniGrid colour indices (empty
      0, goal 0 1, goal 1 4, goal 2 2, lava 5, agent 3 on top); a goal's weight reads 0 once
      collected (its tile stays).
    * ``reward`` ``[*B, 2]`` = (lava, time): time is -3 every step; lava is -20 when moving
      forward into lava or turning while standing in lava (forward from lava into a wall is not
      penalized); collecting goal ``i`` adds ``300 * w_i`` to both.
    * ``original_reward`` ``[*B, 1]``: the authors' single-objective reward for their SAC
      baseline, ``0.9 * lava + 0.1 * time`` (their ``info["original_scalar_reward"]``).
    * terminated after the third goal; truncated after ``max_episode_steps`` (256).

    Args:
        num_envs: number of grids stepped together.
        context: ``[93]`` or ``[num_envs, 93]`` (default: an open interior, see
            :data:`~morl_trl.envs.lava_grid.LAVA_GRID_CONTEXT`).
        device: where the state and TensorDicts live (any torch device).
        seed: seed of the env's :class:`torch.Generator` (on ``device``), used by ``randomize``.
        max_episode_steps: truncation horizon.
        randomize: draw a fresh randomized map (the paper's domain randomization, on
            ``device`` with the env's own generator) for every sub-env at each of its resets,
            ignoring any context in the reset TensorDict. ``make_env("MOLavaGridDR-v0")`` does
            the same with a :class:`~morl_trl.envs.ContextSampler` over this space instead
            (its CPU generator; the same distribution), which honours an explicit context.

    Example:
        >>> import torch
        >>> from morl_trl.envs import make_env
        >>> env = make_env("MOLavaGridRoom-v0", num_envs=2)
        >>> td = env.reset()
        >>> td["observation"].shape
        torch.Size([2, 125])
        >>> td["action"] = torch.tensor([2, 1])       # forward / turn right
        >>> env.step(td)["next", "reward"]
        tensor([[ 0., -3.],
                [ 0., -3.]])
    """

    objective_names = ("lava", "time")

    def __init__(
        self,
        num_envs: int = 1,
        context: torch.Tensor | None = None,
        device: torch.device | str = "cpu",
        seed: int | None = None,
        context_sampler: ContextSampler | None = None,
        allow_extrapolation: bool = False,
        max_episode_steps: int = 256,
        randomize: bool = False,
        context_space: LavaGridContextSpace = LAVA_GRID_CONTEXT,
    ) -> None:
        super().__init__(
            context_space=context_space,
            num_envs=num_envs,
            context=context,
            device=device,
            seed=seed,
            max_episode_steps=max_episode_steps,
            context_sampler=context_sampler,
            allow_extrapolation=allow_extrapolation,
        )
        self.randomize = bool(randomize)
        dev = self.device
        n = num_envs
        self._cells = torch.empty(n, GRID_SIZE * GRID_SIZE, dtype=torch.uint8, device=dev)  # x-major 13x13
        self._colour = torch.empty(n, INNER * INNER, dtype=torch.float32, device=dev)  # obs grid without agent
        self._pos = torch.empty(n, dtype=torch.long, device=dev)  # x * 13 + y
        self._dir = torch.empty(n, dtype=torch.long, device=dev)
        self._collected = torch.empty(n, NUM_GOALS, dtype=torch.bool, device=dev)
        # constant tables
        xs = torch.arange(GRID_SIZE, device=dev)
        x, y = xs[:, None].expand(GRID_SIZE, GRID_SIZE), xs[None, :].expand(GRID_SIZE, GRID_SIZE)
        border = (x == 0) | (y == 0) | (x == GRID_SIZE - 1) | (y == GRID_SIZE - 1)
        ring = ~border & ((x == 1) | (y == 1) | (x == GRID_SIZE - 2) | (y == GRID_SIZE - 2))
        self._frame = (border * WALL + ring * LAVA).to(torch.uint8).reshape(-1)
        # 13x13 index of interior cell (x, y) in 2..10, in the context's row-major-over-y order
        iy, ix = torch.meshgrid(torch.arange(2, 11, device=dev), torch.arange(2, 11, device=dev), indexing="ij")
        self._layout_cells = (ix * GRID_SIZE + iy).reshape(-1)
        self._inner_cells = (x[1:-1, 1:-1] * GRID_SIZE + y[1:-1, 1:-1]).reshape(-1)  # x-major 11x11
        self._obs_index = torch.zeros(GRID_SIZE * GRID_SIZE, dtype=torch.long, device=dev)  # 13x13 -> obs column
        self._obs_index[self._inner_cells] = torch.arange(INNER * INNER, device=dev) + 1 + NUM_GOALS
        self._step_offset = torch.tensor([GRID_SIZE, 1, -GRID_SIZE, -1], device=dev)  # E, S, W, N
        self._colour_table = torch.tensor(_COLOUR_OF_CELL, device=dev)
        self._goal_codes = torch.arange(GOAL0, GOAL0 + NUM_GOALS, device=dev, dtype=torch.uint8)
        self._reset_subenvs(torch.arange(n, device=dev), self._context)

    # ------------------------------------------------------------------ specs
    # the observation is a grid of small integers (tile colours, direction, weights in [0, 1]):
    # it cannot diverge, so the per-step non-finite check covers the reward only
    finite_check_keys = ()

    def _domain_observation_spec(self):
        return {"observation": Bounded(low=0.0, high=5.0, shape=(OBS_SIZE,), dtype=torch.float32)}

    def _domain_action_spec(self):
        return Categorical(3, shape=(), dtype=torch.long)

    # ------------------------------------------------------------------ seeding
    def _seed_subenvs(self, seed: int) -> None:
        self.generator = torch.Generator(device=self.device)
        self.generator.manual_seed(seed)

    # ------------------------------------------------------------------ reset
    def _reset(self, tensordict: TensorDictBase | None = None, **kwargs) -> TensorDictBase:
        if self.randomize:
            mask = self._reset_mask(tensordict)
            idx = mask.nonzero().squeeze(-1)
            context = self._context.clone()
            context[idx] = self.context_space.sample(
                idx.numel(), generator=self.generator, device=self.device, previous=self._context[idx]
            )
            tensordict = (tensordict.clone(False) if tensordict is not None else self.full_state_spec.zero())
            tensordict.set("context", context)
        return super()._reset(tensordict, **kwargs)

    def _reset_subenvs(self, idx: torch.Tensor, context: torch.Tensor) -> None:
        n = idx.numel()
        context = context.to(self.device)
        cells = self._frame.expand(n, -1).clone()
        lava = context[:, LAVA_SLICE].to(torch.uint8) * LAVA
        cells[:, self._layout_cells] = lava
        goals = context[:, GOALS_SLICE].long().reshape(n, NUM_GOALS, 2)
        goal_cells = goals[..., 0] * GRID_SIZE + goals[..., 1]
        cells.scatter_(1, goal_cells, self._goal_codes.expand(n, -1))  # a goal replaces ring lava
        self._cells[idx] = cells
        self._colour[idx] = self._colour_table[cells[:, self._inner_cells].long()]
        self._pos[idx] = context[:, AGENT_X].long() * GRID_SIZE + context[:, AGENT_Y].long()
        self._dir[idx] = context[:, AGENT_DIR].long()
        self._collected[idx] = False

    # ------------------------------------------------------------------ step
    def _observe(self) -> dict[str, torch.Tensor]:
        weights = self._context[:, WEIGHTS_SLICE] * ~self._collected
        obs = torch.cat([self._dir[:, None].float(), weights, self._colour], 1)
        obs.scatter_(1, self._obs_index[self._pos][:, None], AGENT_COLOUR)
        return {"observation": obs}

    def _step_subenvs(self, action: torch.Tensor):
        turn = action < 2
        forward = ~turn
        cells = self._cells
        here = cells.gather(1, self._pos[:, None]).squeeze(1)
        front = self._pos + self._step_offset[self._dir]
        ahead = cells.gather(1, front[:, None]).squeeze(1)

        self._pos = torch.where(forward & (ahead != WALL), front, self._pos)
        self._dir = torch.where(turn, (self._dir + 2 * action - 1) % 4, self._dir)

        lava = (turn & (here == LAVA)) | (forward & (ahead == LAVA))
        new_goal = forward[:, None] & (ahead[:, None] == self._goal_codes) & ~self._collected  # [N, 3]
        self._collected = self._collected | new_goal
        bonus = GOAL_BONUS * (new_goal * self._context[:, WEIGHTS_SLICE]).sum(1)
        reward = torch.stack([lava * LAVA_PENALTY + bonus, bonus + TIME_PENALTY], 1)
        original = reward[:, 0:1] * ORIGINAL_REWARD_WEIGHTS[0] + reward[:, 1:2] * ORIGINAL_REWARD_WEIGHTS[1]
        terminated = self._collected.all(1)
        return self._observe(), reward, original, terminated

    # ------------------------------------------------------------------ snapshots
    _SNAPSHOT = ("_cells", "_colour", "_pos", "_dir", "_collected")

    def _snapshot_subenvs(self) -> dict:
        state = {name: getattr(self, name).clone() for name in self._SNAPSHOT}
        state["generator"] = self.generator.get_state()
        return state

    def _load_snapshot_subenvs(self, state: dict) -> None:
        for name in self._SNAPSHOT:
            self.__dict__[name] = state[name].to(self.device).clone()
        self.generator.set_state(state["generator"])

    # ------------------------------------------------------------------ rendering
    def _render_subenv(self, index: int, tile_size: int = 16) -> np.ndarray:
        """Sub-env ``index`` as an RGB ``uint8`` array ``[13 * tile_size, 13 * tile_size, 3]``
        (``env.render(index, tile_size=...)``).

        Image rows are ``y`` and columns ``x`` (north up); lava is orange, goals are green /
        yellow / blue (dimmed once collected), the agent is a red triangle pointing where it faces.
        """
        from morl_trl.envs.lava_grid.render import render_grid

        return render_grid(
            self._cells[index].reshape(GRID_SIZE, GRID_SIZE).cpu().numpy(),
            collected=self._collected[index].cpu().numpy(),
            agent_pos=divmod(int(self._pos[index]), GRID_SIZE),
            agent_dir=int(self._dir[index]),
            tile_size=tile_size,
        )
