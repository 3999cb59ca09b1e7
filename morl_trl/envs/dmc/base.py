"""The shared machinery of the batched contextual DeepMind Control Suite domains.

A :class:`DMCContextEnv` is a :class:`~morl_trl.envs.mujoco.MujocoContextEnv` (one
``MjModel`` per sub-env carrying its context, stepped by :class:`mujoco.batch.Batch`,
snapshots) whose model is the suite's own (``dm_control.suite.<domain>.get_model_and_assets``)
and whose episodes and steps are the suite's ``control.Environment``'s, so that with the
default context its observations and rewards equal ``dm_control.suite.load``'s for the same
actions and initial state (``tests/envs/test_dmc.py``):

* reset: ``mj_resetData``, a forward pass with actuation disabled, the task's
  ``initialize_episode`` (its random joint angles, drawn from a
  ``numpy.random.RandomState(seed + i)`` for sub-env ``i`` as the suite's ``task_kwargs={"random": seed + i}``),
  another forward pass with actuation disabled. It runs on one scratch ``MjData`` per env,
  sub-env by sub-env (resets only), and the state is then copied into the batch.
* step: dm_control's default "legacy step" is ``mj_step2`` (the position and velocity stages
  are current), ``nstep - 1`` ``mj_step`` and a closing ``mj_step1``; ``Batch.step(nstep,
  stage=mjSTAGE_VEL)`` computes the same (each ``mj_step`` recomputes the stages
  ``mj_step2`` takes as given), so sensors and positions describe the new state.
"""

from __future__ import annotations

import functools
import importlib

import mujoco
import numpy as np
import torch

from morl_trl.envs.base import check_num_envs
from morl_trl.envs.mujoco.base import MujocoContextEnv

__all__ = ["DMCContextEnv", "suite_model"]

_INSTALL = "the DeepMind Control Suite domains need dm_control: pip install 'morl-trl[dmc]'"


def _suite_module(domain: str):
    try:
        return importlib.import_module(f"dm_control.suite.{domain}")
    except ImportError as err:  # (the spec and ids import no simulator; building an env does)
        raise ImportError(f"{_INSTALL} ({err})") from err


@functools.cache
def suite_model(domain: str) -> mujoco.MjModel:
    """The compiled model of ``dm_control.suite.<domain>`` (cached; copy before editing).

    Example:
        >>> suite_model("walker").nu
        6
    """
    xml, assets = _suite_module(domain).get_model_and_assets()
    return mujoco.MjModel.from_xml_string(xml, assets)


def tolerance(x, **kwargs) -> np.ndarray:
    """``dm_control.utils.rewards.tolerance`` (vectorized over numpy arrays)."""
    from dm_control.utils import rewards

    return rewards.tolerance(x, **kwargs)


def small_control(ctrl: np.ndarray) -> np.ndarray:
    """The suite's control-energy term per sub-env, ``[N]``: ``tolerance(ctrl, margin=1,
    value_at_margin=0, sigmoid="quadratic").mean()`` (``hopper.stand``'s ``small_control``)."""
    return tolerance(ctrl, margin=1, value_at_margin=0, sigmoid="quadratic").mean(axis=-1)


def _random_state(seed: int) -> np.random.RandomState:
    """dm_control's task generator ``RandomState(seed)``; beyond its 32-bit seeds, one seeded
    through a ``SeedSequence``."""
    if seed < 2**32:
        return np.random.RandomState(seed)
    return np.random.RandomState(np.random.MT19937(seed))


class DMCContextEnv(MujocoContextEnv):
    """Base of the DeepMind Control Suite domains (see :mod:`morl_trl.envs.dmc.spec` for the
    objectives and the contexts).

    A domain sets ``suite_domain``, ``control_timestep`` (the suite task's; ``None``: one
    physics step per action), ``stiffness_is_factor`` and implements
    :meth:`_initialize_episode`, :meth:`_observation` and :meth:`_rewards`.

    Args: those of :class:`~morl_trl.envs.mujoco.MujocoContextEnv`.
    """

    suite_domain: str = ""
    control_timestep: float | None = None
    #: joint_stiffness multiplies the XML's springs (True) or is the actuated joints' stiffness
    stiffness_is_factor: bool = False
    torso_body: str = "torso"
    nonnegative_context = ("joint_damping", "joint_stiffness")

    def __init__(
        self,
        num_envs: int = 1,
        context: torch.Tensor | None = None,
        device: torch.device | str = "cpu",
        seed: int | None = None,
        context_sampler=None,
        allow_extrapolation: bool = False,
        max_episode_steps: int = 1000,
        num_threads: int | None = None,
    ) -> None:
        num_envs = check_num_envs(num_envs)
        base = self._base_model()
        self._scratch = mujoco.MjData(base)
        self._torso = base.body(self.torso_body).id
        # the actuated joints (walker and hopper: where CARL's default-joint stiffness acts)
        self._actuated = np.unique(base.actuator_trnid[:, 0])
        self._nsub = np.full(num_envs, self._substeps(base.opt.timestep), dtype=np.int64)
        super().__init__(num_envs=num_envs, context=context, device=device, seed=seed,
                         context_sampler=context_sampler, allow_extrapolation=allow_extrapolation,
                         max_episode_steps=max_episode_steps, num_threads=num_threads)
        self.dt = float(self.control_timestep or base.opt.timestep)

    def _base_model(self) -> mujoco.MjModel:
        return suite_model(self.suite_domain)

    def _substeps(self, timestep: float) -> int:
        if self.control_timestep is None:
            return 1
        return max(1, int(round(self.control_timestep / timestep)))

    # ------------------------------------------------------------------ contexts
    def _read_context(self, model: mujoco.MjModel) -> np.ndarray:
        # the default context is the suite's model unchanged (factors 1, the XML's gravity and timestep)
        return np.asarray(self.context_space_.default, dtype=np.float64)

    def _write_context(self, model: mujoco.MjModel, context: np.ndarray) -> None:
        base = self._base_model()
        names = self.context_space_.names
        c = dict(zip(names, context))
        model.opt.gravity[2] = c["gravity"]
        model.geom_friction[:, 0] = base.geom_friction[:, 0] * c["friction"]
        model.actuator_gear[:, 0] = base.actuator_gear[:, 0] * c["actuator_strength"]
        model.dof_damping[:] = base.dof_damping * c["joint_damping"]
        if self.stiffness_is_factor:
            model.jnt_stiffness[:] = base.jnt_stiffness * c["joint_stiffness"]
        else:
            model.jnt_stiffness[:] = base.jnt_stiffness
            model.jnt_stiffness[self._actuated] = c["joint_stiffness"]
        scale = np.full(base.nbody, c["mass"])
        scale[self._torso] *= c["torso_mass"]
        model.body_mass[:] = base.body_mass * scale
        model.body_inertia[:] = base.body_inertia * scale[:, None]
        model.opt.timestep = c["timestep"]
        # the constants derived from masses (subtree masses: the suite's speed sensor)
        mujoco.mj_setConst(model, self._scratch)

    def _apply_contexts(self, ids, context: np.ndarray) -> None:
        super()._apply_contexts(ids, context)
        for i in ids:
            self._nsub[i] = self._substeps(self._models[i].opt.timestep)

    def substeps(self) -> np.ndarray:
        """Physics steps per action of every sub-env, ``[num_envs]`` (from its timestep)."""
        return self._nsub.copy()

    # ------------------------------------------------------------------ seeding / reset
    def _seed_subenvs(self, seed: int) -> None:
        self._rngs = [_random_state(seed + i) for i in range(self.num_envs)]

    def _reset_subenvs(self, idx: torch.Tensor, context: torch.Tensor) -> None:
        ids = self._begin_reset(idx, context)
        data = self._scratch
        fields = {name: self._sim.bind(name) for name in self._STATE_FIELDS}
        for i in ids:
            model = self._models[i]
            # control.Environment.reset: physics.reset_context() around task.initialize_episode
            mujoco.mj_resetData(model, data)
            _forward_without_actuation(model, data)
            self._initialize_episode(model, data, self._rngs[i])
            _forward_without_actuation(model, data)
            for name, target in fields.items():
                target[i] = getattr(data, name)
        self._sim.forward(ids)

    def _initialize_episode(self, model: mujoco.MjModel, data: mujoco.MjData, rng: np.random.RandomState) -> None:
        """The suite task's ``initialize_episode`` on one sub-env's model and data."""
        raise NotImplementedError

    # ------------------------------------------------------------------ step
    def _step_subenvs(self, action: torch.Tensor):
        ctrl, ids = self._set_ctrl(action)
        self._advance(ids)
        reward, original = self._rewards(ctrl)
        terminated = torch.zeros(self.num_envs, dtype=torch.bool, device=self.device)
        return self._observe(), self._to_tensor(reward), self._to_tensor(original), terminated

    def _advance(self, ids: np.ndarray | None) -> None:
        """One action of the sub-envs ``ids`` (``None``: all): dm_control's legacy step."""
        vel = mujoco.mjtStage.mjSTAGE_VEL
        nsub = self._nsub if ids is None else self._nsub[ids]
        if nsub.size == 0:
            return
        first = int(nsub[0])
        if (nsub == first).all():  # the usual case: one call
            self._sim.step(ids, nstep=first, stage=vel)
            return
        all_ids = np.arange(self.num_envs) if ids is None else ids
        for k in np.unique(nsub):  # sub-envs of different timesteps: one call per step count
            self._sim.step(all_ids[nsub == k], nstep=int(k), stage=vel)

    def _rewards(self, ctrl: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``(reward [N, k], original_reward [N])`` after a step (from the bound fields)."""
        raise NotImplementedError


def _forward_without_actuation(model: mujoco.MjModel, data: mujoco.MjData) -> None:
    """dm_control's ``Physics.after_reset``: ``mj_forward`` with actuation disabled."""
    flags = model.opt.disableflags
    model.opt.disableflags = flags | mujoco.mjtDisableBit.mjDSBL_ACTUATION
    try:
        mujoco.mj_forward(model, data)
    finally:
        model.opt.disableflags = flags


def legacy_step(model: mujoco.MjModel, data: mujoco.MjData, nstep: int) -> None:
    """dm_control's default ``Physics.step(nstep)``: ``mj_step2``, ``nstep - 1`` ``mj_step``,
    ``mj_step1`` (the first step takes the stages computed before as current)."""
    mujoco.mj_step2(model, data)
    if nstep > 1:
        mujoco.mj_step(model, data, nstep - 1)
    mujoco.mj_step1(model, data)


def randomize_limited_and_rotational_joints(model: mujoco.MjModel, data: mujoco.MjData,
                                            rng: np.random.RandomState) -> None:
    """``dm_control.suite.utils.randomizers.randomize_limited_and_rotational_joints`` for the
    planar models (hinge and slide joints): a limited joint uniform in its range, an unlimited
    hinge uniform in ``[-pi, pi]``, in joint order, one draw each."""
    hinge, slide = int(mujoco.mjtJoint.mjJNT_HINGE), int(mujoco.mjtJoint.mjJNT_SLIDE)
    for j in range(model.njnt):
        kind = int(model.jnt_type[j])
        if kind not in (hinge, slide):
            raise ValueError(f"joint {j} has type {kind}; only hinge and slide joints are supported")
        adr = model.jnt_qposadr[j]
        if model.jnt_limited[j]:
            low, high = model.jnt_range[j]
            data.qpos[adr] = rng.uniform(low, high)
        elif kind == hinge:
            data.qpos[adr] = rng.uniform(-np.pi, np.pi)
