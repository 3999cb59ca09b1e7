"""MO-LunarLander (discrete and continuous) as one batched TorchRL environment.

``N`` Box2D worlds, one per sub-env, each with its own context (SPEC §1.1). Only the calls
that must touch a world (apply forces, ``Step``, read the lander back) loop over sub-envs;
wind, engine impulses, observations, shaping, rewards and termination are numpy operations
over the batch, written in Gymnasium's operation order so that the results are the same
floating-point numbers as ``LunarLander-v3`` / MO-Gymnasium's ``mo-lunar-lander-v3``.
"""

from __future__ import annotations

import numpy as np
import torch
from Box2D import _Box2D
from torchrl.data import Bounded, Categorical, Unbounded

from morl_trl.envs.base import ContextualMOEnv
from morl_trl.envs.lunar_lander import physics as P
from morl_trl.envs.lunar_lander.random_streams import BlockUniformStreams
from morl_trl.envs.specs.lunar_lander import LUNAR_LANDER_CONTEXT, OBJECTIVES

__all__ = ["MOLunarLanderEnv"]

_GRAVITY, _WIND, _TURBULENCE, _MAIN, _SIDE, _X, _Y = range(7)
_HALF_W, _HALF_H = P.VIEWPORT_W / P.SCALE / 2, P.VIEWPORT_H / P.SCALE / 2
# Gymnasium's state from (x, y, vx, vy, angle, angular velocity): (x - W/2) / (W/2),
# (y - pad) / (H/2), vx * (W/2) / FPS, vy * (H/2) / FPS, angle, 20 * w / FPS. As one
# (v * mul - sub) / div whose extra factors (* 1, - 0, / 1) are exact: the same floats.
_OBS_MUL = np.array([1.0, 1.0, _HALF_W, _HALF_H, 1.0, 20.0])
_OBS_SUB = np.array([_HALF_W, P.HELIPAD_Y + P.LEG_DOWN / P.SCALE, 0.0, 0.0, 0.0, 0.0])
_OBS_DIV = np.array([_HALF_W, _HALF_H, P.FPS, P.FPS, 1.0, P.FPS])
# discrete action -> (main power, side power, side direction), as Gymnasium derives them
_MAIN_POWER = np.array([0.0, 0.0, 1.0, 0.0])
_SIDE_POWER = np.array([0.0, 1.0, 0.0, 1.0])
_DIRECTION = np.array([-2.0, -1.0, 0.0, 1.0])

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


def _engine_impulses(body, ctx, disp, main, side, direction):
    """Per sub-env ``(impulse x, impulse y, point x, point y)`` rows of the main and the side
    engine, as lists, or ``None`` for an engine that fires nowhere; the loop applies a row
    only where that engine fires (``main > 0``, ``side > 0``).

    ``body`` ``[n, 6]`` is the lander state read back after the previous step, ``disp``
    ``[n, 2]`` the step's dispersion (already divided by ``SCALE``).
    """
    fire_main, fire_side = main > 0, side > 0
    any_main, any_side = fire_main.any(), fire_side.any()
    if not (any_main or any_side):
        return None, None
    d0, d1 = disp[:, 0], disp[:, 1]
    px, py, angle = body[:, 0], body[:, 1], body[:, 4]
    tip0, tip1 = np.sin(angle), np.cos(angle)
    side0, side1 = -tip1, tip0
    main_kicks = side_kicks = None
    if any_main:
        lever = P.MAIN_ENGINE_Y_LOCATION / P.SCALE + 2 * d0
        ox = tip0 * lever + side0 * d1
        oy = -tip1 * lever - side1 * d1
        power = ctx[:, _MAIN]
        main_kicks = _rows(-ox * power * main, -oy * power * main, px + ox, py + oy)
    if any_side:
        arm = 3 * d1 + direction * P.SIDE_ENGINE_AWAY / P.SCALE
        ox = tip0 * d0 + side0 * arm
        oy = -tip1 * d0 - side1 * arm
        power = ctx[:, _SIDE]
        x = px + ox - tip0 * 17 / P.SCALE  # Gymnasium's 17 (not SIDE_ENGINE_HEIGHT), kept
        y = py + oy + tip1 * P.SIDE_ENGINE_HEIGHT / P.SCALE
        side_kicks = _rows(-ox * power * side, -oy * power * side, x, y)
    return main_kicks, side_kicks


def _rows(*columns) -> list:
    out = np.empty((len(columns[0]), len(columns)))
    for j, c in enumerate(columns):
        out[:, j] = c
    return out.tolist()


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
        self._wind_idx = np.zeros((n, 2), dtype=np.int64)  # wind and torque indices
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
            self._streams = BlockUniformStreams(self.num_envs, seed)
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
            w = P.build_world(self._streams.generator(i), g, x, y, self._listeners[i])
            self._worlds[i] = w
            self._landers[i], self._world_steps[i] = w.lander, w.world.Step
            self._wind_idx[i] = (w.wind_idx, w.torque_idx)
        self._ready = self._ready or all(w is not None for w in self._worlds)
        # Gymnasium's reset ends with one no-op step whose observation it returns
        zeros = np.zeros(len(idx))
        state, shaping, _ = self._advance(idx, zeros, zeros, zeros)
        self._prev_shaping[idx] = shaping
        self._obs[idx] = state  # _obs is never shared with a returned tensor (see _step_subenvs)

    def _observe(self):
        return {"observation": torch.tensor(self._obs, device=self.device)}

    # ------------------------------------------------------------------ step
    def _engine_powers(self, action: torch.Tensor):
        """(main power, side power, side direction) per sub-env, as Gymnasium derives them."""
        a = action.detach().cpu().numpy()
        if self.continuous:
            a = np.clip(a, -1, +1).astype(np.float64)
            main = np.where(a[:, 0] > 0.0, (np.clip(a[:, 0], 0.0, 1.0) + 1.0) * 0.5, 0.0)
            fire_side = np.abs(a[:, 1]) > 0.5
            side = np.where(fire_side, np.clip(np.abs(a[:, 1]), 0.5, 1.0), 0.0)
            direction = np.sign(a[:, 1])
        else:  # noop, left, main, right -> main power 0/1, side power 0/1, direction a - 2
            main, side, direction = _MAIN_POWER[a], _SIDE_POWER[a], _DIRECTION[a]
        return main, side, direction

    def _step_subenvs(self, action: torch.Tensor):
        if not self._ready:
            raise RuntimeError("MOLunarLanderEnv: call reset() before step()")
        main, side, direction = self._engine_powers(action)
        n = self.num_envs
        if self._active is None or bool(self._active.all()):
            idx, sel = self._all, slice(None)
        else:  # a partial step: only the selected worlds advance (e.g. the evaluator's unfinished episodes)
            idx = np.flatnonzero(self._active.cpu().numpy())
            sel = idx
            main, side, direction = main[idx], side[idx], direction[idx]
        state, shaping, awake = self._advance(idx, main, side, direction)

        shaping_delta = shaping - self._prev_shaping[sel]
        self._prev_shaping[sel] = shaping
        crashed = self._game_over[sel] | (np.abs(state[:, 0]) >= 1.0)  # float64 x, as Gymnasium tests it
        at_rest = ~awake
        landing = np.where(at_rest, 100.0, np.where(crashed, -100.0, 0.0))
        original = shaping_delta - main * 0.30 - side * 0.03
        done = crashed | at_rest
        if sel is idx:
            reward = np.zeros((n, 4), dtype=np.float32)
            original_all = np.zeros(n, dtype=np.float32)
            terminated = np.zeros(n, dtype=bool)
        else:
            reward = np.empty((n, 4), dtype=np.float32)
            original_all = np.empty(n, dtype=np.float32)
            terminated = np.empty(n, dtype=bool)
        for j, column in enumerate((landing, shaping_delta, 0.0 - main, 0.0 - side)):
            reward[sel, j] = column
        original_all[sel] = np.where(done, landing, original)
        terminated[sel] = done

        # a fresh array: the returned tensor lives on in rollouts while _obs is updated at resets
        obs = self._obs.copy()
        obs[sel] = state
        self._obs[sel] = state
        dev = self.device
        return (
            {"observation": torch.from_numpy(obs).to(dev)},
            torch.from_numpy(reward).to(dev),
            torch.from_numpy(original_all).to(dev),
            torch.from_numpy(terminated).to(dev),
        )

    def _advance(self, idx: np.ndarray, main: np.ndarray, side: np.ndarray, direction: np.ndarray):
        """One Gymnasium step of the worlds ``idx`` with the given engine powers.

        Returns the observations ``[n, 8]`` (float64: Gymnasium's ``state`` before its cast
        to float32), the shaping ``[n]`` and the landers' ``awake`` flags ``[n]``. Every
        expression keeps Gymnasium's operation order, so the floats are the same.
        """
        every = len(idx) == self.num_envs
        sel = slice(None) if every else idx  # views instead of gathers on the common path
        ctx = self._ctx[sel]
        # wind and turbulence act only while no leg touches the ground
        airborne = ~self._legs[sel].any(axis=1)
        k = self._wind_idx[sel].astype(np.float64)  # columns: wind, torque
        wind = np.tanh(np.sin(P.WIND_K1 * k) + np.sin(P.WIND_K2 * k)) * ctx[:, _WIND : _TURBULENCE + 1]
        self._wind_idx[sel] += airborne[:, None]
        disp = self._streams.take(None if every else idx) / P.SCALE  # drawn at every step, engines firing or not
        main_kicks, side_kicks = _engine_impulses(self._body[sel], ctx, disp, main, side, direction)

        landers = self._landers if every else [self._landers[i] for i in idx.tolist()]
        steps = self._world_steps if every else [self._world_steps[i] for i in idx.tolist()]
        readback = []
        push = readback.extend
        dt, vel_iters, pos_iters = P.TIME_STEP, P.VELOCITY_ITERATIONS, P.POSITION_ITERATIONS
        n = len(idx)
        no_kicks = [None] * n
        for lander, step, air, (force, torque), fire_main, main_kick, fire_side, side_kick in zip(
            landers, steps, airborne.tolist(), wind.tolist(),
            (main > 0).tolist(), main_kicks or no_kicks, (side > 0).tolist(), side_kicks or no_kicks,
        ):
            if air:
                _apply_force(lander, (force, 0.0), True)
                _apply_torque(lander, torque, True)
            if fire_main:
                _apply_impulse(lander, (main_kick[0], main_kick[1]), (main_kick[2], main_kick[3]), True)
            if fire_side:
                _apply_impulse(lander, (side_kick[0], side_kick[1]), (side_kick[2], side_kick[3]), True)
            step(dt, vel_iters, pos_iters)
            pos, vel = _position(lander), _velocity(lander)
            push((_x(pos), _y(pos), _x(vel), _y(vel), _angle(lander), _spin(lander), _awake(lander)))

        back = np.array(readback, dtype=np.float64).reshape(n, 7)
        self._body[sel] = back[:, :6]
        s = np.empty((len(idx), 8))
        s[:, :6] = (back[:, :6] * _OBS_MUL - _OBS_SUB) / _OBS_DIV
        s[:, 6:] = self._legs[sel]
        sq = s[:, 0:4] * s[:, 0:4]
        hundred_norms = 100 * np.sqrt(sq[:, 0::2] + sq[:, 1::2])  # 100 |(x, y)|, 100 |(vx, vy)|
        legs = 10 * s[:, 6:]
        shaping = -hundred_norms[:, 0] - hundred_norms[:, 1] - 100 * np.abs(s[:, 4]) + legs[:, 0] + legs[:, 1]
        return s, shaping, back[:, 6] > 0

    # ------------------------------------------------------------------ rendering
    def render(self, index: int | None = 0, *, mode: str = "rgb_array") -> np.ndarray:
        """RGB image ``[400, 600, 3]`` (uint8) of sub-env ``index``; all of them
        ``[num_envs, 400, 600, 3]`` with ``index=None``. Needs Pillow, opens no window.

        Works with TorchRL's ``PixelRenderTransform(index=None)`` to record every sub-env.
        """
        from morl_trl.envs.lunar_lander.render import render_world

        if mode != "rgb_array":
            raise ValueError(f"render mode {mode!r} is not supported; only 'rgb_array'")
        if not self._ready:
            raise RuntimeError("MOLunarLanderEnv: call reset() before render()")
        if index is None:
            return np.stack([render_world(w) for w in self._worlds])
        if not -self.num_envs <= index < self.num_envs:
            raise ValueError(f"index {index} is out of range for {self.num_envs} sub-envs")
        return render_world(self._worlds[index])
