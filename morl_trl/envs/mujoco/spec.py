"""MO-Hopper, MO-HalfCheetah, MO-Humanoid (SPEC §1.2): contexts are masses, damping, friction.

Data only: imports no simulator (``mujoco``) and not the registry, which reads :data:`SPECS`.
"""

from morl_trl.envs.context import ContextSpace
from morl_trl.envs.spec import DomainSpec, SORLReward

# Declared bounds of the MuJoCo contexts (the range the physics is valid in; the DR ranges
# below are narrower, and every evaluation context lies inside):
# masses [0.01, 100] kg: 10x below the lightest evaluation body (0.1, Humanoid and Hopper) and
#   10x above the heaviest DR mass; outside, the mass ratios of the chain make MuJoCo's
#   integrator unstable (a 1e6 kg Hopper torso gives NaN within ~50 steps);
# damping [0, 50]: 0 is an undamped joint, 50 is 5x the largest DR damping;
# friction [0.01, 10]: a near-frictionless floor to far beyond rubber on concrete (~1).
_MASS = (0.01, 100.0)
_DAMPING = (0.0, 50.0)
_FRICTION = (0.01, 10.0)

# ---------------------------------------------------------------- Hopper
_HOPPER_MASS = ("torso", "thigh", "leg", "foot")
HOPPER_CONTEXT = ContextSpace(
    names=tuple(f"mass_{b}" for b in _HOPPER_MASS)
    + ("damping_thigh", "damping_leg", "damping_foot", "friction"),
    default=(3.6652, 4.0579, 2.7814, 5.3156, 1.0, 1.0, 1.0, 1.0),
    low=(0.1,) * 4 + (0.1,) * 3 + (0.1,),
    high=(10.0,) * 4 + (3.0,) * 3 + (3.0,),
    positive=tuple(f"mass_{b}" for b in _HOPPER_MASS) + ("friction",),
    valid_low=(_MASS[0],) * 4 + (_DAMPING[0],) * 3 + (_FRICTION[0],),
    valid_high=(_MASS[1],) * 4 + (_DAMPING[1],) * 3 + (_FRICTION[1],),
)


def _hopper(masses, damping, friction):
    m = dict(zip((f"mass_{b}" for b in _HOPPER_MASS), masses))
    d = {n: damping for n in ("damping_thigh", "damping_leg", "damping_foot")}
    return {**m, **d, "friction": friction}


_HOPPER = {
    "Default": {},
    "Light": _hopper((0.5, 0.5, 0.3, 0.7), 1.0, 1.0),
    "Heavy": _hopper((9.0, 9.0, 8.5, 10.0), 1.0, 1.0),
    "Slippery": _hopper((3.7, 4.0, 2.8, 5.3), 1.0, 0.1),
    "LowDamping": _hopper((3.7, 4.0, 2.8, 5.3), 0.1, 1.0),
    "Hard": _hopper((0.1, 9.0, 9.0, 0.1), 0.1, 0.1),
}

# ---------------------------------------------------------------- HalfCheetah
_CHEETAH_MASS = ("torso", "bthigh", "bshin", "bfoot", "fthigh", "fshin", "ffoot")
_CHEETAH_DEFAULT = (6.2502, 1.5435, 1.5874, 1.0954, 1.4381, 1.2008, 0.8845)
CHEETAH_CONTEXT = ContextSpace(
    names=tuple(f"mass_{b}" for b in _CHEETAH_MASS) + ("friction",),
    default=_CHEETAH_DEFAULT + (0.4,),
    low=(0.1,) * 7 + (0.1,),
    high=(10.0,) * 7 + (2.0,),
    positive=tuple(f"mass_{b}" for b in _CHEETAH_MASS) + ("friction",),
    valid_low=(_MASS[0],) * 7 + (_FRICTION[0],),
    valid_high=(_MASS[1],) * 7 + (_FRICTION[1],),
)


def _cheetah(masses, friction):
    return {**dict(zip((f"mass_{b}" for b in _CHEETAH_MASS), masses)), "friction": friction}


_CHEETAH = {
    "Default": {},
    "Light": _cheetah((0.5,) + (0.1,) * 6, 0.4),
    "Heavy": _cheetah((10.0,) + (9.5,) * 6, 0.4),
    "Slippery": _cheetah(_CHEETAH_DEFAULT, 0.1),
    "Hard": _cheetah((6.2502, 9.5, 9.5, 9.5, 0.1, 0.1, 0.1), 0.1),
}

# ---------------------------------------------------------------- Humanoid
_HUMANOID_MASS = (
    "torso", "lwaist", "pelvis", "right_thigh", "right_shin", "right_foot",
    "left_thigh", "left_shin", "left_foot", "right_upper_arm", "right_lower_arm",
    "left_upper_arm", "left_lower_arm",
)  # fmt: skip
_HUMANOID_MASS_DEFAULT = (
    8.9075, 2.2619, 6.6162, 4.7518, 2.7557, 1.7671, 4.7518, 2.7557, 1.7671, 1.6611, 1.2295, 1.6611, 1.2295,
)  # fmt: skip
_HUMANOID_DOF = (
    "abdomen_z", "abdomen_y", "abdomen_x", "right_hip_x", "right_hip_z", "right_hip_y", "right_knee",
    "left_hip_x", "left_hip_z", "left_hip_y", "left_knee", "right_shoulder1", "right_shoulder2",
    "right_elbow", "left_shoulder1", "left_shoulder2", "left_elbow",
)  # fmt: skip
_HUMANOID_DAMP_DEFAULT = (5.0,) * 6 + (1.0,) + (5.0,) * 3 + (1.0,) * 7
# U(1,10) for the joints whose default damping is 5, U(0.2,5) for knees and arms
_HUMANOID_DAMP_LOW = tuple(1.0 if d == 5.0 else 0.2 for d in _HUMANOID_DAMP_DEFAULT)
_HUMANOID_DAMP_HIGH = tuple(10.0 if d == 5.0 else 5.0 for d in _HUMANOID_DAMP_DEFAULT)
HUMANOID_CONTEXT = ContextSpace(
    names=tuple(f"mass_{b}" for b in _HUMANOID_MASS) + tuple(f"damping_{j}" for j in _HUMANOID_DOF),
    default=_HUMANOID_MASS_DEFAULT + _HUMANOID_DAMP_DEFAULT,
    low=(0.5,) * 13 + _HUMANOID_DAMP_LOW,
    high=(10.0,) * 13 + _HUMANOID_DAMP_HIGH,
    positive=tuple(f"mass_{b}" for b in _HUMANOID_MASS),
    # the evaluation masses go down to 0.1, below the DR minimum 0.5 (SPEC §1.2)
    valid_low=(_MASS[0],) * 13 + (_DAMPING[0],) * 17,
    valid_high=(_MASS[1],) * 13 + (_DAMPING[1],) * 17,
)


def _humanoid(masses=_HUMANOID_MASS_DEFAULT, damping=_HUMANOID_DAMP_DEFAULT):
    return {
        **dict(zip((f"mass_{b}" for b in _HUMANOID_MASS), masses)),
        **dict(zip((f"damping_{j}" for j in _HUMANOID_DOF), damping)),
    }


_LOW_DAMPING = (1.0,) * 6 + (0.2,) + (1.0,) * 3 + (0.2,) * 7
_HUMANOID = {
    "Default": {},
    "Light": _humanoid((1.7, 0.5, 1.3, 0.7, 0.6, 0.5, 0.7, 0.5, 0.3, 0.3, 0.1, 0.3, 0.1)),
    "Heavy": _humanoid((10.0, 7.0, 9.0, 8.0, 7.0, 6.0, 8.0, 7.0, 6.0, 6.0, 5.5, 6.0, 5.5)),
    "LowDamping": _humanoid(damping=_LOW_DAMPING),
    "Hard": _humanoid((8.9075, 2.2619, 6.6162, 0.7, 0.6, 0.5, 8.0, 7.0, 6.0, 0.1, 0.1, 5.0, 5.0), _LOW_DAMPING),
}

# ---------------------------------------------------------------- f_SORL (the paper's appendix
# "Single Objective Utility Function Results"; v_x forward speed, c = -sum(a**2) the control
# cost, h the healthy reward). The healthy bonus is in every vector objective (SPEC §1.2), so
# it comes back as an offset: f = w . r + offset exactly, step by step (tests/envs/test_sorl.py).
_HOPPER_SORL = SORLReward(
    paper="1.5 v_x + 0.001 c + h",
    # r = [v_x + 1, 10 dz + 1, c + 1]: f = (r0 - 1) + 0.001 (r2 - 1) + 1
    weights=(1.0, 0.0, 0.001),
    offset=-0.001,
    note="the paper writes 1.5 v_x, but what was measured is 1.0 v_x: the authors' MOHopperDR has "
         "forward_reward_weight=1.0 (Gymnasium Hopper-v5's default) and is registered without an override, "
         "and its info['original_scalar_reward'] (SAC's reward, the summed single-objective return) uses it. "
         "The healthy term h = 1 is paid on the terminating step too, as in the authors' env.",
)
_CHEETAH_SORL = SORLReward(paper="1.0 v_x + 0.1 c", weights=(1.0, 0.1))  # r = [v_x, c]
_HUMANOID_SORL = SORLReward(
    paper="1.25 v_x + 0.001 c + 2.0 h",
    # r = [v_x + 2, c + 2]: f = 1.25 (r0 - 2) + 0.001 (r1 - 2) + 2
    weights=(1.25, 0.001),
    offset=-0.502,
    note="the vector's forward objective drops the 1.25 (SPEC §5.9); the healthy term 2.0 is paid on the "
         "terminating step too, as in the authors' env (Gymnasium Humanoid-v5: 5.0, the paper lowered it).",
)

SPECS = tuple(
    DomainSpec(
        name=f"MO-{_name}",
        train_id=f"MO{_name}DR-v5",
        env_class=f"morl_trl.envs.mujoco:MO{_name}Env",
        context_space=_space,
        contexts={f"MO{_name}{k}-v5": v for k, v in _contexts.items()},
        evaluation_ids=tuple(f"MO{_name}{k}-v5" for k in _contexts),
        objective_names=_objectives,
        gamma=0.99,
        hv_ref_point=_ref,
        max_episode_steps=1000,
        history_len=2,
        train_frames=_frames,
        eval_interval=100_000,
        sorl=_sorl,
    )
    for _name, _space, _contexts, _objectives, _ref, _frames, _sorl in (
        ("Hopper", HOPPER_CONTEXT, _HOPPER, ("forward", "jump", "energy"), (-100.0,) * 3, 3_000_000, _HOPPER_SORL),
        ("HalfCheetah", CHEETAH_CONTEXT, _CHEETAH, ("forward", "energy"), (-100.0, -500.0), 5_000_000, _CHEETAH_SORL),
        ("Humanoid", HUMANOID_CONTEXT, _HUMANOID, ("forward", "energy"), (-100.0, -100.0), 10_000_000,
         _HUMANOID_SORL),
    )
)
