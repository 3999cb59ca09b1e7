"""MO-LunarLander (discrete and continuous) as one batched TorchRL environment.

``N`` Box2D worlds, one per sub-env, each with its own context (SPEC §1.1). Only the calls
that must touch a world (apply forces, ``Step``, read the lander back) loop over sub-envs;
wind, engine impulses, observations, shaping, rewards and termination are numpy operations
over the batch, written in Gymnasium's operation order so that the results are the same
floating-point numbers as ``LunarLander-v3`` / MO-Gymnasium's ``mo-lunar-lander-v3``.
"""

from __future__ import annotations

import math

import numpy as np
import torch
from Box2D import _Box2D
from torchrl.data import Bounded, Categorical, Unbounded

from morl_trl.envs.base import ContextualMOEnv
from morl_trl.envs.sampler import ContextSampler
from morl_trl.envs.lunar_lander import physics as P
from morl_trl.envs.lunar_lander.random_streams import BlockUniformStreams
from morl_trl.envs.lunar_lander.spec import LUNAR_LANDER_CONTEXT, OBJECTIVES

__all__ = ["MOLunarLanderEnv"]

_GRAVITY, _WIND, _TURBULENCE, _MAIN, _SIDE, _X, _Y = range(7)
_HALF_W, _HALF_H = P.VIEWPORT_W / P.SCALE / 2, P.VIEWPORT_H / P.SCALE / 2
# Gymnasium's state from (x, y, vx, vy, angle, angular velocity): (x - W/2) / (W/2),
# (y - pad) / (H/2), vx * (W/2) / FPS, vy * (H/2) / FPS, angle, 20 * w / FPS. As one
# (v * mul - sub) / div whose extra factors (* 1, - 0, / 1) are exact: the same floats.
_OBS_MUL = np.array([1.0, 1.0, _HALF_W, _HALF_H, 1.0, 20.0])
_OBS_SUB = np.array([_HALF_W, P.HELIPAD_Y + P.LEG_DOWN / P.SCALE, 0.0, 0.0, 0.0, 0.0])
_OBS_DIV = np.array([_HALF_W, _HALF_H, P.FPS, P.FPS, 1.0, P.FPS])
# per-step engine terms, one row per sub-env: main power, side power, 0, side direction *
# SIDE_ENGINE_AWAY / SCALE (the side engine's lateral offset, as Gymnasium computes it)
_DISCRETE_ENGINES = np.array([  # noop, left, main, right (direction = action - 2)
    [0.0, 0.0, 0.0, -2.0 * P.SIDE_ENGINE_AWAY / P.SCALE],
    [0.0, 1.0, 0.0, -1.0 * P.SIDE_ENGINE_AWAY / P.SCALE],
    [1.0, 0.0, 0.0, 0.0 * P.SIDE_ENGINE_AWAY / P.SCALE],
    [0.0, 1.0, 0.0, 1.0 * P.SIDE_ENGINE_AWAY / P.SCALE],
])
# both engines at once, as [n, 2] columns (main, side): the offset (ox, oy) of an engine is
# tip * a + side * b with a = (MAIN_Y / SCALE + 2 d0, d0), b = (d1, 3 d1 + lateral offset)
_A_MUL, _A_ADD = np.array([2.0, 1.0]), np.array([P.MAIN_ENGINE_Y_LOCATION / P.SCALE, 0.0])
_B_MUL = np.array([1.0, 3.0])
# impulse point: the main engine at the offset, the side engine further up the lander by
# (-tip0 * 17, tip1 * SIDE_ENGINE_HEIGHT) / SCALE (Gymnasium's 17, not SIDE_ENGINE_HEIGHT, kept)
_X_UP, _Y_UP, _UP_DIV = np.array([0.0, 17.0]), np.array([0.0, P.SIDE_ENGINE_HEIGHT]), np.array([1.0, P.SCALE])

# pybox2d's C entry points, called directly in the per-world loop: its Python properties
# and methods only forward to these, at about twice the cost
_apply_force = _Box2D.b2Body_ApplyForceToCenter
_apply_torque = _Box2D.b2Body_ApplyTorque
_apply_impulse = _Box2D.b2Body_ApplyLinearImpulse
_position = _Box2D.b2Body___GetPosition
_velocity = _Box2D.b2Body___GetLinearVelocity
_angle = _Box2D.b2Body___GetAngle
_spin = _Box2D.b2Body___GetAngularVelocity
_awake = _Box2D.b2Body___IsAwake
_x, _y = _Box2D.b2Vec2_x_get, _Box2D.b2Vec2_y_get


def _as_decimal_float64(context: torch.Tensor) -> np.ndarray:
    """float32 contexts -> the float64 of their shortest decimal (0.6f -> 0.6, not 0.6000000238).

    Contexts travel as float32 while Gymnasium computes in float64 from decimal literals;
    going through the shortest decimal gives the same physics as the float64 peer for the
    values people type (all the paper's contexts).
    """
    rows = context.detach().cpu().numpy().astype(np.float32)
    key = rows.tobytes()
    out = _DECIMAL_CACHE.get(key)
    if out is None:  # the string round trip costs tens of us: remembered (auto-resets repeat contexts)
        out = rows.astype(str).astype(np.float64)
        if len(_DECIMAL_CACHE) >= 1024:
            _DECIMAL_CACHE.clear()
        _DECIMAL_CACHE[key] = out
    return out.copy()


_DECIMAL_CACHE: dict[bytes, np.ndarray] = {}


class _WindTable:
    """Gymnasium's wind and turbulence profile ``tanh(sin(0.02 k) + sin(pi * 0.01 k))`` by
    integer index ``k``, tabulated with Gymnasium's own ``math`` calls (the same floats).

    Rows store ``k + OFFSET``, a valid table index: the initial indices lie in
    ``[-9999, 9999)`` and grow by one per airborne step; :meth:`ensure` extends the table.
    """

    OFFSET = 9999

    def __init__(self) -> None:
        self.values = np.empty(0)
        self.ensure(2 * self.OFFSET + 2048)

    def ensure(self, size: int) -> None:
        old = len(self.values)
        if size > old:
            size = max(size, 2 * old)
            k1, k2 = P.WIND_K1, P.WIND_K2
            more = [math.tanh(math.sin(k1 * k) + math.sin(k2 * k)) for k in range(old - self.OFFSET, size - self.OFFSET)]
            self.values = np.concatenate([self.values, np.array(more)])


_WIND_TABLE = _WindTable()


def _engine_impulses(body: np.ndarray, ctx: np.ndarray, disp: np.ndarray, engines: np.ndarray) -> list:
    """Per sub-env ``[impulse x, impulse y, point x, point y]`` of each engine, interleaved
    (main, side, main, side, ...) as Gymnasium computes them; the loop applies an engine only
    where it fires.

    ``body`` ``[n, 6]`` is the lander state read back after the previous step, ``disp``
    ``[n, 2]`` the step's dispersion (already divided by ``SCALE``), ``engines`` ``[n, 4]``
    the rows of :data:`_DISCRETE_ENGINES`. Columns are (main, side) throughout.
    """
    angle = body[:, 4]
    tip0, tip1 = np.sin(angle)[:, None], np.cos(angle)[:, None]
    side0 = -tip1  # side = (-tip1, tip0)
    a = disp[:, :1] * _A_MUL + _A_ADD
    b = disp[:, 1:] * _B_MUL + engines[:, 2:]
    ox = tip0 * a + side0 * b
    oy = side0 * a - tip0 * b  # -tip1 * a - side1 * b
    power = ctx[:, _MAIN : _SIDE + 1]
    kick_x = -ox * power * engines[:, :2]
    kick_y = -oy * power * engines[:, :2]
    at_x = body[:, :1] + ox - tip0 * _X_UP / _UP_DIV
    at_y = body[:, 1:2] + oy + tip1 * _Y_UP / _UP_DIV
    return np.concatenate((kick_x, kick_y, at_x, at_y), 1).tolist()


class MOLunarLanderEnv(ContextualMOEnv):
    """Batched contextual MO-LunarLander with a 4-D reward.

    Observation ``[*B, 8]`` as Gymnasium's; action ``Categorical(4)`` (noop, left, main,
    right) or, with ``continuous=True``, ``Box(2)`` in ``[-1, 1]`` (main throttle, lateral).
    Reward ``[*B, 4]`` = (landing: -100 crash or out of bounds / +100 at rest, on the
    terminal step; shaping: the step's change of Gymnasium's shaping; main_fuel: -main
    engine power; side_fuel: -side engine power). ``"original_reward"`` is Gymnasium's
    scalar reward. Context (7 entries): gravity, wind_power, turbulence_power,
    main_engine_power, side_engine_power, initial_x_coeff, initial_y_coeff; wind and
    turbulence are always enabled (set their power to 0 to switch them off).

    Sub-env ``i``'s random generator is seeded like Gymnasium's ``reset(seed=seed + i)``
    and continues across its episodes, so with the same seed, context and actions a
    sub-env reproduces ``LunarLander-v3(enable_wind=True)`` draw for draw.

    Args:
        num_envs: number of sub-environments.
        context: ``[7]`` or ``[num_envs, 7]``; the default context if ``None``.
        device: device of the output TensorDicts (the physics runs on the CPU).
        seed: seed of the sub-envs' generators.
        continuous: continuous actions (``MOLunarLanderContinuous*``).
        max_episode_steps: truncation horizon (1000 in the paper).

    Example:
        >>> from morl_trl.envs import make_env
        >>> env = make_env("MOLunarLanderHard-v0", num_envs=4, seed=0)
        >>> td = env.rollout(5)
        >>> td["next", "reward"].shape, td["next", "observation"].shape
        (torch.Size([4, 5, 4]), torch.Size([4, 5, 8]))
        >>> env.objective_names
        ('landing', 'shaping', 'main_fuel', 'side_fuel')
    """

    objective_names = OBJECTIVES

    def __init__(
        self,
        num_envs: int = 1,
        context: torch.Tensor | None = None,
        device: torch.device | str = "cpu",
        seed: int | None = None,
        context_sampler: ContextSampler | None = None,
        allow_extrapolation: bool = False,
        continuous: bool = False,
        max_episode_steps: int = 1000,
    ) -> None:
        self.continuous = bool(continuous)
        self._streams: BlockUniformStreams | None = None
        super().__init__(
            context_space=LUNAR_LANDER_CONTEXT,
            num_envs=num_envs,
            context=context,
            device=device,
            seed=seed,
            max_episode_steps=max_episode_steps,
            context_sampler=context_sampler,
            allow_extrapolation=allow_extrapolation,
        )
        n = num_envs
        self._all = np.arange(n)
        self._worlds: list[P.LanderWorld | None] = [None] * n
        self._landers: list = [None] * n  # the worlds' lander bodies and bound Step methods
        self._world_steps: list = [None] * n
        self._ready = False  # every sub-env has been reset at least once
        self._ctx = np.zeros((n, self.context_space.dim))
        # written by the contact listeners during Box2D steps
        self._game_over = np.zeros(n, dtype=bool)
        self._legs = np.zeros((n, 2), dtype=bool)
        self._listeners = [P.ContactFlags(self._game_over, self._legs, i) for i in range(n)]
        self._wind_idx = np.zeros((n, 2), dtype=np.int64)  # wind and torque indices, + _WIND_TABLE.OFFSET
        self._wind_guard = [0]  # steps the wind table is known to cover for every sub-env (a list: cheap to update)
        self._body = np.zeros((n, 6))  # x, y, vx, vy, angle, angular velocity (last read back)
        self._obs = np.zeros((n, 8), dtype=np.float32)
        self._prev_shaping = np.zeros(n)

    # ------------------------------------------------------------------ specs / seeding
    def _domain_observation_spec(self):
        return {"observation": Unbounded(shape=(8,), dtype=torch.float32)}

    def _domain_action_spec(self):
        if self.continuous:
            return Bounded(low=-1.0, high=1.0, shape=(2,), dtype=torch.float32)
        return Categorical(4, shape=(), dtype=torch.long)

    def _seed_subenvs(self, seed: int) -> None:
        if self._streams is None:
            self._streams = BlockUniformStreams(self.num_envs, seed, divisor=P.SCALE)  # Gymnasium's u / SCALE
        else:
            self._streams.seed(seed)

    # ------------------------------------------------------------------ reset
    def _reset_subenvs(self, idx: torch.Tensor, context: torch.Tensor) -> None:
        idx = idx.cpu().numpy()
        ctx = _as_decimal_float64(context)
        self._ctx[idx] = ctx
        self._game_over[idx] = False
        self._legs[idx] = False
        for i, (g, x, y) in zip(idx.tolist(), ctx[:, [_GRAVITY, _X, _Y]].tolist()):
            old = self._worlds[i]
            if old is not None:
                old.world.contactListener = None
                # freed before the new world is built, so that Box2D's allocations reuse its
                # memory: building into fresh pages costs several times more
                self._worlds[i] = self._landers[i] = self._world_steps[i] = old = None
            w = P.build_world(self._streams.generator(i), g, x, y, self._listeners[i])
            self._worlds[i] = w
            self._landers[i], self._world_steps[i] = w.lander, w.world.Step
            self._wind_idx[i] = (w.wind_idx + _WIND_TABLE.OFFSET, w.torque_idx + _WIND_TABLE.OFFSET)
        if not self._ready:
            self._ready = all(w is not None for w in self._worlds)
        # Gymnasium's reset ends with one no-op step whose observation it returns
        state, shaping, _ = self._advance(idx, np.zeros((len(idx), 4)))
        self._prev_shaping[idx] = shaping
        obs = self._obs.copy()  # out of place: step outputs share the previous array
        obs[idx] = state
        self.__dict__["_obs"] = obs

    def _observe(self):
        # _obs is replaced, never written in place, after it is handed out: no copy needed
        return {"observation": torch.from_numpy(self._obs).to(self.device)}

    # ------------------------------------------------------------------ step
    def _engines(self, action: torch.Tensor) -> np.ndarray:
        """``[n, 4]``: main power, side power, 0, side direction * SIDE_ENGINE_AWAY / SCALE,
        as Gymnasium derives them from the actions."""
        a = action.numpy() if action.device.type == "cpu" else action.detach().cpu().numpy()
        if not self.continuous:
            return _DISCRETE_ENGINES[a]
        a = np.clip(a, -1, +1).astype(np.float64)
        engines = np.zeros((len(a), 4))
        engines[:, 0] = np.where(a[:, 0] > 0.0, (np.clip(a[:, 0], 0.0, 1.0) + 1.0) * 0.5, 0.0)
        engines[:, 1] = np.where(np.abs(a[:, 1]) > 0.5, np.clip(np.abs(a[:, 1]), 0.5, 1.0), 0.0)
        engines[:, 3] = np.sign(a[:, 1]) * P.SIDE_ENGINE_AWAY / P.SCALE
        return engines

    def _step_subenvs(self, action: torch.Tensor):
        if not self._ready:
            raise RuntimeError("MOLunarLanderEnv: call reset() before step()")
        engines = self._engines(action)
        n = self.num_envs
        active = self._active
        if active is None or bool(active.all()):
            idx = sel = self._all
        else:  # a partial step: only the selected worlds advance (e.g. the evaluator's unfinished episodes)
            idx = np.flatnonzero(active.cpu().numpy())
            sel = idx
            engines = engines[idx]
        state, shaping, at_rest = self._advance(idx, engines)
        full = sel is self._all
        if full:
            sel = slice(None)  # views instead of gathers

        shaping_delta = shaping - self._prev_shaping[sel]
        self._prev_shaping[sel] = shaping
        crashed = self._game_over[sel] | (np.abs(state[:, 0]) >= 1.0)  # float64 x, as Gymnasium tests it
        landing = np.where(at_rest, 100.0, np.where(crashed, -100.0, 0.0))
        done = crashed | at_rest
        original = np.where(done, landing, shaping_delta - engines[:, 0] * 0.30 - engines[:, 1] * 0.03)
        if full:
            reward = np.empty((n, 4), dtype=np.float32)
            original_all = original.astype(np.float32)
            terminated = done
        else:  # the skipped rows are zeros
            reward = np.zeros((n, 4), dtype=np.float32)
            original_all = np.zeros(n, dtype=np.float32)
            terminated = np.zeros(n, dtype=bool)
            original_all[sel] = original
            terminated[sel] = done
        reward[sel, 0] = landing
        reward[sel, 1] = shaping_delta
        reward[sel, 2:] = 0.0 - engines[:, :2]  # main_fuel, side_fuel (0.0 - p: no -0.0 when idle)

        if full:
            obs = state.astype(np.float32)
        else:
            obs = self._obs.copy()
            obs[sel] = state
        self.__dict__["_obs"] = obs  # shared with the returned tensor: resets write a copy
        out = torch.from_numpy(obs), torch.from_numpy(reward), torch.from_numpy(original_all), torch.from_numpy(terminated)
        if self.device.type != "cpu":
            out = tuple(t.to(self.device) for t in out)
        return {"observation": out[0]}, *out[1:]

    def _advance(self, idx: np.ndarray, engines: np.ndarray):
        """One Gymnasium step of the worlds ``idx`` with the given engine rows ``[n, 4]``.

        Returns the observations ``[n, 8]`` (float64: Gymnasium's ``state`` before its cast
        to float32), the shaping ``[n]`` and whether each lander has come to rest ``[n]``.
        Every expression keeps Gymnasium's operation order, so the floats are the same.
        """
        n = len(idx)
        every = idx is self._all
        sel = slice(None) if every else idx  # views instead of gathers on the common path
        ctx = self._ctx[sel]
        # wind and turbulence act only while no leg touches the ground
        legs = self._legs[sel]
        airborne = ~(legs[:, 0] | legs[:, 1])
        guard = self._wind_guard
        if guard[0] <= 0:
            self._extend_wind_table()
        guard[0] -= 1
        wind = _WIND_TABLE.values[self._wind_idx[sel]] * ctx[:, _WIND : _TURBULENCE + 1]  # columns: wind, torque
        self._wind_idx[sel] += airborne[:, None]
        disp = self._streams.take(None if every else idx)  # u / SCALE, drawn at every step, engines firing or not
        fire = engines[:, :2] > 0
        if fire.any():
            kicks = _engine_impulses(self._body[sel], ctx, disp, engines)
            fire = fire.tolist()
        else:
            kicks = fire = [(False, False)] * n  # (a reset's no-op step)

        landers = self._landers if every else [self._landers[i] for i in idx.tolist()]
        steps = self._world_steps if every else [self._world_steps[i] for i in idx.tolist()]
        readback = []
        push = readback.extend
        dt, vel_iters, pos_iters = P.TIME_STEP, P.VELOCITY_ITERATIONS, P.POSITION_ITERATIONS
        for lander, step, air, (force, torque), (fire_main, fire_side), kick in zip(
            landers, steps, airborne.tolist(), wind.tolist(), fire, kicks
        ):
            if air:
                _apply_force(lander, (force, 0.0), True)
                _apply_torque(lander, torque, True)
            if fire_main:
                _apply_impulse(lander, (kick[0], kick[2]), (kick[4], kick[6]), True)
            if fire_side:
                _apply_impulse(lander, (kick[1], kick[3]), (kick[5], kick[7]), True)
            step(dt, vel_iters, pos_iters)
            pos, vel = _position(lander), _velocity(lander)
            push((_x(pos), _y(pos), _x(vel), _y(vel), _angle(lander), _spin(lander), _awake(lander)))

        back = np.array(readback, dtype=np.float64).reshape(n, 7)
        body = back[:, :6]
        if every:
            self.__dict__["_body"] = body
        else:
            self._body[idx] = body
        s = np.empty((n, 8))
        s[:, :6] = (body * _OBS_MUL - _OBS_SUB) / _OBS_DIV
        s[:, 6:] = self._legs[sel]
        sq = s[:, 0:4] * s[:, 0:4]
        hundred_norms = 100 * np.sqrt(sq[:, 0::2] + sq[:, 1::2])  # 100 |(x, y)|, 100 |(vx, vy)|
        legs = 10 * s[:, 6:]
        shaping = -hundred_norms[:, 0] - hundred_norms[:, 1] - 100 * np.abs(s[:, 4]) + legs[:, 0] + legs[:, 1]
        return s, shaping, back[:, 6] == 0

    def _extend_wind_table(self) -> None:
        """Make sure the wind table covers the next steps of every sub-env (see ``_wind_guard``)."""
        top = max(int(self._wind_idx.max()), 2 * _WIND_TABLE.OFFSET)  # a reset starts below 2 * OFFSET
        _WIND_TABLE.ensure(top + 4096)
        self._wind_guard[0] = len(_WIND_TABLE.values) - 1 - top  # each step (or reset) adds at most one

    # ------------------------------------------------------------------ rendering
    def _render_subenv(self, index: int) -> np.ndarray:
        """RGB image ``[400, 600, 3]`` (uint8) of sub-env ``index`` (``env.render(index)``; all of
        them with ``index=None``). Needs Pillow, opens no window."""
        from morl_trl.envs.lunar_lander.render import render_world

        if not self._ready:
            raise RuntimeError("MOLunarLanderEnv: call reset() before render()")
        return render_world(self._worlds[index])
