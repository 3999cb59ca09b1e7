"""Contextual MO domains on the DeepMind Control Suite (beyond the paper): contexts and ids.

Data only: imports no simulator (neither ``mujoco`` nor ``dm_control``) and not the registry,
which reads :data:`SPECS`.

Domains (``dm_control.suite`` task -> our training id; every fixed context ``DMC<Task><Name>-v0``):

========================  ===========================  =================================
suite task                training id                  objectives (each per step in [0, 1])
========================  ===========================  =================================
``walker``/``walk``       ``DMCWalkerDR-v0``           ``speed, stand, energy``
``walker``/``run``        ``DMCWalkerRunDR-v0``        ``speed, stand, energy``
``cheetah``/``run``       ``DMCCheetahDR-v0``          ``speed, energy``
``hopper``/``hop``        ``DMCHopperDR-v0``           ``hop, stand, energy``
========================  ===========================  =================================

Objectives are the suite task's own terms, kept apart, each built with
``dm_control.utils.rewards.tolerance`` exactly as the task's ``get_reward`` builds it (so each
lies in ``[0, 1]`` per step), plus control energy as the suite's ``small_control`` term
(``hopper.stand``, ``humanoid``): ``tolerance(ctrl, margin=1, value_at_margin=0,
sigmoid="quadratic").mean()`` ``= 1 - mean(ctrl**2)`` for actions in ``[-1, 1]``:

* Walker (walk: ``v* = 1`` m/s; run: ``v* = 8``): ``speed = tolerance(v_com_x, (v*, inf),
  margin=v*/2, value_at_margin=0.5, sigmoid="linear")``; ``stand = (3 * tolerance(torso_z,
  (1.2, inf), margin=0.6) + (1 + torso_zz) / 2) / 4``. Suite reward ``stand * (5 * speed + 1) / 6``.
* Cheetah: ``speed = tolerance(v_com_x, (10, inf), margin=10, value_at_margin=0,
  sigmoid="linear")`` (``= clip(v / 10, 0, 1)``). Suite reward ``speed``.
* Hopper: ``hop = tolerance(v_com_x, (2, inf), margin=1, value_at_margin=0.5,
  sigmoid="linear")``; ``stand = tolerance(torso_z - foot_z, (0.6, 2))``. Suite reward
  ``stand * hop``.

``original_reward`` is the suite's reward. Episodes last the suite's time limit, 1000 actions
(walker 25 s at 0.025 s, cheetah 10 s at 0.01 s, hopper 20 s at 0.02 s), and never terminate.

Contexts follow CARL's DMC context features (CARL scales the XML's values: tangential
friction, joint damping, actuator gear and geom density are factors; gravity and timestep are
absolute), here written into each sub-env's compiled model instead of its XML:

* ``gravity`` (m/s^2, z component; default -9.81): ``opt.gravity[2]``.
* ``friction`` (factor; CARL's ``friction_tangential``): ``geom_friction[:, 0]`` of every geom.
* ``actuator_strength`` (factor): ``actuator_gear[:, 0]`` of every motor.
* ``joint_damping`` (factor): ``dof_damping`` of every dof.
* ``joint_stiffness``: Cheetah's XML has joint springs, so it is a factor on them (default 1);
  Walker's and Hopper's have none, so, as CARL's default-joint stiffness, it is the stiffness
  (N m/rad, default 0) of every actuated joint, spring rest at the XML pose.
* ``mass`` (factor; CARL's ``geom_density``, which scales each body's mass and inertia): every
  body's ``body_mass`` and ``body_inertia``; ``torso_mass`` (factor) the torso's again.
* ``timestep`` (s; default the XML's): ``opt.timestep``. Each action lasts
  ``round(control_timestep / timestep)`` physics steps (at least 1): dm_control's
  ``compute_n_steps`` where the timestep divides the suite's control interval, the nearest
  count otherwise (so the control interval stays within half a physics step of the suite's).

After writing masses, ``mj_setConst`` recomputes the model's derived constants (subtree
masses, used by the suite's ``subtreelinvel`` speed sensor); at the default context it leaves
the compiled model bit for bit as it was.

Evaluation suite (every domain): ``Default``, ``Light`` (mass 0.5), ``Heavy`` (mass 2),
``Slippery`` (friction 0.2), ``WeakMotors`` (actuator_strength 0.5), ``LowGravity`` (gravity
-4.905), ``Hard`` (torso_mass 2, friction 0.2, actuator_strength 0.5). All lie inside the DR
ranges. No reference fronts exist for these domains: reports give hypervolume and EUM only
(NHGR needs specialist fronts).
"""

from morl_trl.envs.context import ContextSpace
from morl_trl.envs.spec import DomainSpec

_NAMES = ("gravity", "friction", "actuator_strength", "joint_damping", "joint_stiffness", "mass", "torso_mass",
          "timestep")
_POSITIVE = ("friction", "actuator_strength", "mass", "torso_mass", "timestep")


def _space(stiffness: tuple[float, float, float, float, float], timestep: tuple[float, float, float, float, float]):
    """The family's context space; ``stiffness``/``timestep`` = (default, low, high, valid_low, valid_high)."""
    rows = (
        # default, DR low, DR high, valid low, valid high
        (-9.81, -14.715, -4.905, -30.0, -0.1),  # gravity: 0.5x-1.5x; CARL's upper bound -0.1
        (1.0, 0.2, 1.5, 0.01, 10.0),  # friction
        (1.0, 0.5, 1.5, 0.05, 5.0),  # actuator_strength
        (1.0, 0.5, 2.0, 0.0, 20.0),  # joint_damping
        stiffness,
        (1.0, 0.5, 2.0, 0.1, 10.0),  # mass
        (1.0, 0.5, 2.0, 0.1, 10.0),  # torso_mass
        timestep,
    )
    default, low, high, vlow, vhigh = zip(*rows)
    return ContextSpace(names=_NAMES, default=default, low=low, high=high, positive=_POSITIVE,
                        valid_low=vlow, valid_high=vhigh)


# joint_stiffness: absolute N m/rad (no springs in the XML) vs a factor on the XML's springs
WALKER_CONTEXT = _space((0.0, 0.0, 5.0, 0.0, 100.0), (0.0025, 0.002, 0.003, 0.0005, 0.005))
CHEETAH_CONTEXT = _space((1.0, 0.5, 1.5, 0.0, 10.0), (0.01, 0.008, 0.012, 0.002, 0.02))
HOPPER_CONTEXT = _space((0.0, 0.0, 5.0, 0.0, 100.0), (0.005, 0.004, 0.006, 0.001, 0.01))

#: the evaluation suite of every DMC domain (overrides of the default context)
EVALUATION_CONTEXTS = {
    "Default": {},
    "Light": {"mass": 0.5},
    "Heavy": {"mass": 2.0},
    "Slippery": {"friction": 0.2},
    "WeakMotors": {"actuator_strength": 0.5},
    "LowGravity": {"gravity": -4.905},
    "Hard": {"torso_mass": 2.0, "friction": 0.2, "actuator_strength": 0.5},
}


def _spec(name: str, cls: str, space: ContextSpace, objectives: tuple[str, ...], env_kwargs=None) -> DomainSpec:
    return DomainSpec(
        name=f"DMC-{name}",
        train_id=f"DMC{name}DR-v0",
        env_class=f"morl_trl.envs.dmc:{cls}",
        context_space=space,
        contexts={f"DMC{name}{k}-v0": v for k, v in EVALUATION_CONTEXTS.items()},
        evaluation_ids=tuple(f"DMC{name}{k}-v0" for k in EVALUATION_CONTEXTS),
        objective_names=objectives,
        env_kwargs=env_kwargs or {},
        gamma=0.99,
        # every objective is in [0, 1] per step: discounted returns are >= 0
        hv_ref_point=(0.0,) * len(objectives),
        max_episode_steps=1000,
        history_len=2,
        train_frames=1_000_000,
        eval_interval=50_000,
        eval_weights=32,
    )


SPECS = (
    _spec("Walker", "DMCWalkerEnv", WALKER_CONTEXT, ("speed", "stand", "energy"), {"task": "walk"}),
    _spec("WalkerRun", "DMCWalkerEnv", WALKER_CONTEXT, ("speed", "stand", "energy"), {"task": "run"}),
    _spec("Cheetah", "DMCCheetahEnv", CHEETAH_CONTEXT, ("speed", "energy")),
    _spec("Hopper", "DMCHopperEnv", HOPPER_CONTEXT, ("hop", "stand", "energy")),
)
