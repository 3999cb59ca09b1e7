"""The shared machinery of the batched contextual MuJoCo domains (SPEC §1.2).

Each sub-env owns its own :class:`mujoco.MjModel` (a copy of the domain's compiled XML) and
:class:`mujoco.MjData`, so each can carry its own context: the context is written straight
into the model's ``body_mass`` / ``dof_damping`` / ``pair_friction`` entries (no inertia
rescale, no ``mj_setConst``, as the paper's code does).

The sub-envs are stepped by :class:`mujoco.batch.Batch` (MuJoCo >= 3.17): one call runs
``mj_step(model_i, data_i, nstep=frame_skip)`` for every sub-env on a C++ thread pool, and
``qpos``/``qvel``/``xipos``/... of all sub-envs are live ``[N, ...]`` numpy arrays, so there
is no per-sub-env Python on the step path (Humanoid's ``mj_rnePostConstraint``, see
:class:`MOHumanoidEnv`, is the one exception). Its results are bit-identical to a loop over one ``MjData`` per sub-env,
so the physics is step for step Gymnasium's (``tests/envs/test_mujoco.py`` checks it).
We measured the alternatives: a Python loop of ``mujoco.mj_step`` holds the GIL (no second core) and costs a
few microseconds per sub-env; :func:`mujoco.rollout` is threaded too, but restarts each
call from a copied state with a cold solver warm-start and keeps no ``MjData`` per sub-env,
so trajectories drift from Gymnasium's and Humanoid's ``cinert``/``cfrc_ext`` would need an
extra ``mj_forward`` per sub-env.
"""

from __future__ import annotations

import copy
import functools
import os
import warnings
from importlib import resources

import mujoco
import numpy as np
import torch
from mujoco.batch import Batch
from torchrl.data import Bounded, Unbounded

from morl_trl.envs.base import ContextualMOEnv
from morl_trl.envs.sampler import ContextSampler
from morl_trl.envs.context import ContextSpace

__all__ = ["MujocoContextEnv", "load_model"]


@functools.cache
def load_model(xml_name: str) -> mujoco.MjModel:
    """The compiled model of one of the package's XML assets (cached; copy before editing)."""
    path = resources.files("morl_trl.envs.mujoco").joinpath("assets", xml_name)

    def forward(message: str) -> None:
        # half_cheetah.xml keeps Gymnasium's settotalmass (see the note in that file)
        if "settotalmass" not in message:
            warnings.warn(f"MuJoCo: {message}", RuntimeWarning, stacklevel=2)

    previous = mujoco.get_mju_user_warning()
    mujoco.set_mju_user_warning(forward)
    try:
        return mujoco.MjModel.from_xml_path(str(path))
    finally:
        mujoco.set_mju_user_warning(previous)


def _usable_cpus() -> int:
    if hasattr(os, "sched_getaffinity"):
        return len(os.sched_getaffinity(0))
    return os.cpu_count() or 1


def _as_decimal_float64(context: np.ndarray) -> np.ndarray:
    """float32 contexts -> the float64 of their shortest decimal (0.1f -> 0.1, not 0.100000001).

    Contexts travel as float32; writing the decimal a person typed keeps a model built from a
    context such as ``friction=0.1`` identical to one built in float64 from the literal.
    """
    return np.asarray(context, dtype=np.float32).astype(str).astype(np.float64)


def _rng_state(rng) -> dict:
    """The state of a ``numpy.random.Generator`` or a legacy ``RandomState`` (dm_control's)."""
    return rng.bit_generator.state if isinstance(rng, np.random.Generator) else rng.get_state(legacy=False)


def _set_rng_state(rng, state: dict) -> None:
    if isinstance(rng, np.random.Generator):
        rng.bit_generator.state = state
    else:
        rng.set_state(state)


class MujocoContextEnv(ContextualMOEnv):
    """Base of :class:`MOHopperEnv`, :class:`MOHalfCheetahEnv` and :class:`MOHumanoidEnv`.

    A domain sets the class attributes below and implements :meth:`_read_context` /
    :meth:`_write_context` (model arrays <-> context), :meth:`_reset_noise` (Gymnasium's
    initial-state noise), :meth:`_observation` and :meth:`_rewards`.

    Observations are ``float32``; the physics runs in ``float64`` on the CPU whatever
    ``device`` the TensorDicts live on. Sub-env ``i`` draws its reset noise from
    ``numpy.random.default_rng(seed + i)``, continued across its episodes, which is what
    ``gymnasium_env.reset(seed=seed + i)`` followed by plain resets does.

    A context entry equal to its registered default (the XML value rounded to 4 decimals)
    leaves the XML's exact value in the model, so the ``*Default-v5`` ids are exactly the XML
    models, as in the paper's code, where the Default envs never call ``set_task``.

    Args:
        num_envs, context, device, seed, max_episode_steps: see
            :class:`~morl_trl.envs.ContextualMOEnv`.
        num_threads: threads that step the sub-envs (results do not depend on it); default
            ``min(num_envs, usable CPUs)``.
    """

    xml_file: str = ""
    frame_skip: int = 1
    reset_noise_scale: float = 0.0
    context_space_: ContextSpace
    objective_names: tuple[str, ...] = ()
    observation_dim: int = 0
    #: the render camera (Gymnasium's view of the domain): a tracking camera on this body
    render_camera: dict = {"track_body": 1, "distance": 4.0, "elevation": -20.0}
    # MuJoCo data fields the domain reads from every sub-env, bound as live [N, ...] arrays
    _bound_fields: tuple[str, ...] = ("qpos", "qvel", "ctrl")
    #: context entries MuJoCo must not get negative (the ContextSpace lets them through under
    #: ``allow_extrapolation``); ``None``: the joint dampings, every ``damping_*``
    nonnegative_context: tuple[str, ...] | None = None

    def __init__(
        self,
        num_envs: int = 1,
        context: torch.Tensor | None = None,
        device: torch.device | str = "cpu",
        seed: int | None = None,
        context_sampler: ContextSampler | None = None,
        allow_extrapolation: bool = False,
        max_episode_steps: int = 1000,
        num_threads: int | None = None,
    ) -> None:
        self._rngs: list[np.random.Generator] = []
        super().__init__(
            context_space=self.context_space_,
            num_envs=num_envs,
            context=context,
            device=device,
            seed=seed,
            max_episode_steps=max_episode_steps,
            context_sampler=context_sampler,
            allow_extrapolation=allow_extrapolation,
        )
        if num_threads is None:
            num_threads = min(num_envs, _usable_cpus())
        if not isinstance(num_threads, int) or num_threads < 1:
            raise ValueError(f"num_threads must be a positive int, got {num_threads!r}")
        base = self._base_model()
        self._models = [copy.copy(base) for _ in range(num_envs)]
        self._init_qpos = base.qpos0.copy()
        self._init_qvel = np.zeros(base.nv)
        self.dt = float(base.opt.timestep * self.frame_skip)
        self._xml_context = self._read_context(base)
        self._default_f32 = np.asarray(self.context_space_.default, dtype=np.float32)
        self._body_mass = np.tile(base.body_mass, (num_envs, 1))
        names = self.context_space_.names
        nonnegative = self.nonnegative_context
        if nonnegative is None:
            nonnegative = tuple(n for n in names if n.startswith("damping_"))
        self._nonnegative_columns = np.array([names.index(n) for n in nonnegative], dtype=np.int64)
        context = self._context.cpu().numpy()
        self._check_physics(context)
        self._apply_contexts(range(num_envs), context)
        self._sim = Batch(base, num_envs, nthread=num_threads, persistent=True)
        self._sim.set_models(self._models)
        # bound before the first call: derived fields fill in at every call
        self._fields = {name: self._sim.bind(name) for name in self._bound_fields}
        # the state before the first reset: the XML's initial pose, no noise drawn (as
        # Gymnasium's MujocoEnv after construction), so that reset(seed) matches theirs
        self._sim.reset()

    # ------------------------------------------------------------------ specs
    def _domain_observation_spec(self):
        return {"observation": Unbounded(shape=(self.observation_dim,), dtype=torch.float32)}

    def _domain_action_spec(self):
        low, high = self._base_model().actuator_ctrlrange.T
        return Bounded(
            low=torch.as_tensor(low, dtype=torch.float32),
            high=torch.as_tensor(high, dtype=torch.float32),
            shape=(len(low),),
            dtype=torch.float32,
        )

    # ------------------------------------------------------------------ models
    def _base_model(self) -> mujoco.MjModel:
        """The domain's compiled model, shared by every instance (copy it before editing)."""
        return load_model(self.xml_file)

    @property
    def num_threads(self) -> int:
        return self._sim.nthread

    @property
    def mj_models(self) -> tuple[mujoco.MjModel, ...]:
        """The sub-envs' models, each carrying its sub-env's context (read them, don't edit)."""
        return tuple(self._models)

    def mj_data(self, i: int) -> mujoco.MjData:
        """A copy of sub-env ``i``'s simulation state (the whole ``MjData``)."""
        return self._sim.get_data(i)

    def _read_context(self, model: mujoco.MjModel) -> np.ndarray:
        """The context a model carries (the inverse of :meth:`_write_context`)."""
        raise NotImplementedError

    def _write_context(self, model: mujoco.MjModel, context: np.ndarray) -> None:
        """Write a float64 context ``[c]`` into the model arrays SPEC names."""
        raise NotImplementedError

    def _apply_contexts(self, ids, context: np.ndarray) -> None:
        """Write the contexts ``[len(ids), c]`` into the models of the sub-envs ``ids``."""
        values = _as_decimal_float64(context)
        at_default = np.asarray(context, dtype=np.float32) == self._default_f32
        values = np.where(at_default, self._xml_context, values)
        for i, row in zip(ids, values):
            self._write_context(self._models[i], row)
            self._body_mass[i] = self._models[i].body_mass

    def _check_physics(self, context: np.ndarray) -> None:
        """Reject what the ContextSpace lets through but MuJoCo should not get (a negative
        :attr:`nonnegative_context` entry), before any state changes."""
        bad = context[:, self._nonnegative_columns] < 0
        if bad.any():
            row, k = (int(v) for v in np.argwhere(bad)[0])
            col = self._nonnegative_columns[k]
            raise ValueError(
                f"context parameter {self.context_space_.names[col]!r} is {float(context[row, col])} "
                f"(row {row}); it must be >= 0"
            )

    # ------------------------------------------------------------------ seeding
    def _seed_subenvs(self, seed: int) -> None:
        self._rngs = [np.random.default_rng(seed + i) for i in range(self.num_envs)]

    def reseed_subenvs(self, seeds) -> None:
        seeds = [int(s) for s in seeds]
        if len(seeds) != self.num_envs:
            raise ValueError(f"reseed_subenvs needs one seed per sub-env ({self.num_envs}), got {len(seeds)}")
        self._rngs = [np.random.default_rng(s) for s in seeds]  # (Gymnasium's np_random for reset(seed=s))

    # ------------------------------------------------------------------ reset / step
    def _reset_noise(self, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
        """``(qpos, qvel)`` of a fresh episode, drawn as the Gymnasium v5 env draws them."""
        raise NotImplementedError

    def _begin_reset(self, idx: torch.Tensor, context: torch.Tensor) -> np.ndarray:
        """The shared start of a reset of the sub-envs ``idx``: check and write their contexts
        ``[len(idx), c]`` (checked before anything changes), hand the models to the batch and
        ``mj_resetData`` them; returns ``idx`` as a numpy array."""
        context = context.cpu().numpy()
        self._check_physics(context)  # before anything changes
        ids = idx.cpu().numpy()
        self._apply_contexts(ids, context)
        self._sim.set_models(self._models)  # Batch's contract after editing a model
        self._sim.reset(ids, stage=mujoco.mjtStage.mjSTAGE_NONE)
        return ids

    def _reset_subenvs(self, idx: torch.Tensor, context: torch.Tensor) -> None:
        # Gymnasium's reset: mj_resetData, noisy qpos/qvel, mj_forward
        ids = self._begin_reset(idx, context)
        qpos, qvel = self._fields["qpos"], self._fields["qvel"]
        for i in ids:
            qpos[i], qvel[i] = self._reset_noise(self._rngs[i])
        self._sim.forward(ids)
        self._after_reset(ids)

    def _after_reset(self, ids: np.ndarray) -> None:
        """Hook: refresh domain state of the sub-envs ``ids`` after their reset."""

    def _after_step(self, ids: np.ndarray | None) -> None:
        """Hook: run after every step of the sub-envs ``ids`` (``None``: all)."""

    def _x_position(self) -> np.ndarray:
        """The x coordinate whose change per ``dt`` is the forward velocity."""
        return self._fields["qpos"][:, 0].copy()

    def _observe(self):
        return {"observation": self._to_tensor(self._observation())}

    def _step_subenvs(self, action: torch.Tensor):
        x_before = self._x_position()
        ctrl, ids = self._set_ctrl(action)
        if ids is None:  # the usual full step
            self._sim.step(nstep=self.frame_skip)
        elif ids.size:  # a TorchRL partial step: the other sub-envs keep their state
            self._sim.step(ids, nstep=self.frame_skip)
        self._after_step(ids)
        x_velocity = (self._x_position() - x_before) / self.dt
        reward, original, terminated = self._rewards(x_velocity, ctrl)
        terminated = torch.from_numpy(terminated).to(self.device)
        return self._observe(), self._to_tensor(reward), self._to_tensor(original), terminated

    def _set_ctrl(self, action: torch.Tensor) -> tuple[np.ndarray, np.ndarray | None]:
        """Write the action into the controls of the sub-envs to step; returns ``(ctrl [N, nu]
        float64, ids)``, ``ids`` ``None`` for a full step, else the active sub-envs (TorchRL's
        partial step: the others keep their state)."""
        ctrl = action.detach().to("cpu", torch.float64).numpy()
        if self._active is None:
            self._fields["ctrl"][:] = ctrl
            return ctrl, None
        ids = np.flatnonzero(self._active.cpu().numpy())
        self._fields["ctrl"][ids] = ctrl[ids]
        return ctrl, ids

    def _to_tensor(self, array: np.ndarray) -> torch.Tensor:
        return torch.from_numpy(np.ascontiguousarray(array, dtype=np.float32)).to(self.device)

    # ------------------------------------------------------------------ rendering
    def _render_subenv(self, index: int, width: int = 480, height: int = 480) -> np.ndarray:
        """RGB ``uint8 [height, width, 3]`` of sub-env ``index`` through ``mujoco.Renderer``
        (headless: see :mod:`morl_trl.envs.mujoco.render` for the GL backend)."""
        from morl_trl.envs.mujoco.render import MujocoFrameRenderer

        renderers = self.__dict__.setdefault("_renderers", {})
        if (width, height) not in renderers:
            renderers[(width, height)] = MujocoFrameRenderer(self._base_model(), width=width, height=height,
                                                             **self.render_camera)
        data = self._sim.get_data(index)
        import mujoco

        mujoco.mj_forward(self._models[index], data)  # (positions of the state; a copy: the sim is untouched)
        return renderers[(width, height)].render(data)

    # ------------------------------------------------------------------ snapshots
    # the physics state of every sub-env (MuJoCo's mjSTATE_INTEGRATION: time, qpos, qvel, act,
    # warm start, controls, mocap, userdata); derived fields are recomputed by mj_forward
    _STATE_FIELDS = ("time", "qpos", "qvel", "act", "qacc_warmstart", "ctrl", "mocap_pos", "mocap_quat", "userdata")

    def _snapshot_subenvs(self) -> dict:
        # (+ the bound fields a domain reads: after a step, derived ones are those of the step's
        # start, which a fresh mj_forward would not reproduce)
        names = dict.fromkeys((*self._STATE_FIELDS, *self._bound_fields))
        fields = {name: np.array(self._sim.bind(name), copy=True) for name in names}
        return {"fields": fields, "rngs": [_rng_state(g) for g in self._rngs],
                "extra": {k: np.array(v, copy=True) for k, v in self._snapshot_extra().items()}}

    def _load_snapshot_subenvs(self, state: dict) -> None:
        self._apply_contexts(range(self.num_envs), self._context.cpu().numpy())
        self._sim.set_models(self._models)
        for name in self._STATE_FIELDS:
            self._sim.bind(name)[...] = state["fields"][name]
        self._sim.forward()  # the derived fields (positions, inertias) of the restored state
        for name, value in state["fields"].items():  # then the fields as they were (warm start, bound)
            target = self._sim.bind(name)  # (a binding of its own: derived fields bind read-only, and the
            target.setflags(write=True)    # next call recomputes them; the domain's bindings stay as they are)
            target[...] = value
        for g, st in zip(self._rngs, state["rngs"]):
            _set_rng_state(g, st)
        for k, v in state["extra"].items():
            getattr(self, k)[...] = v

    def _snapshot_extra(self) -> dict[str, np.ndarray]:
        """Hook: domain arrays (attribute name -> array) that are state, not derived by mj_forward."""
        return {}

    # ------------------------------------------------------------------ domain hooks
    def _observation(self) -> np.ndarray:
        """``[N, observation_dim]`` float64 from the bound fields."""
        raise NotImplementedError

    def _rewards(self, x_velocity: np.ndarray, ctrl: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(reward [N, k], original_reward [N], terminated [N] bool)`` after a step."""
        raise NotImplementedError
