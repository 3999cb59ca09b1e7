"""MO-LunarLander (SPEC §1.1): 7 context parameters, 8 (+2) evaluation contexts, 4 objectives.

Data only: imports no simulator (Box2D) and not the registry, which reads :data:`SPECS`.
"""

from morl_trl.envs.context import ContextSpace
from morl_trl.envs.spec import DomainSpec, SORLReward

LUNAR_LANDER_CONTEXT = ContextSpace(
    names=(
        "gravity",
        "wind_power",
        "turbulence_power",
        "main_engine_power",
        "side_engine_power",
        "initial_x_coeff",
        "initial_y_coeff",
    ),
    default=(-10.0, 15.0, 1.5, 13.0, 0.6, 0.5, 1.0),
    low=(-13.0, 0.0, 0.0, 10.0, 0.3, 0.25, 0.7),
    high=(-7.0, 20.0, 3.5, 16.0, 0.9, 0.75, 1.0),
    positive=("main_engine_power", "side_engine_power", "initial_x_coeff", "initial_y_coeff"),
    # declared bounds: where the Box2D physics stays meaningful (the DR range above is narrower).
    # gravity: downward, at most twice the hardest DR value; -0.5 keeps a lander that still
    #   falls (Gymnasium asserts -12 < g < 0, which the authors disabled: LowGravity is g=-3);
    # wind / turbulence: non-negative magnitudes, up to 1.5x the DR maxima;
    # engine powers: strictly positive (a dead engine makes its action a no-op), up to 40
    #   (2.5x the DR maximum main power);
    # spawn coefficients: a fraction of the viewport, (0, 1] (1.0 is Gymnasium's own spawn).
    valid_low=(-20.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0),
    valid_high=(-0.5, 30.0, 5.0, 40.0, 40.0, 1.0, 1.0),
)

# name -> overrides of the default context (SPEC §1.1 "Eval overrides")
_CONTEXTS = {
    "Default": {},
    "HighGravity": {"gravity": -13.0},
    "Windy": {"wind_power": 20.0},
    "Turbulent": {"turbulence_power": 3.5},
    "Hard": {
        "gravity": -12.0,
        "wind_power": 17.0,
        "turbulence_power": 2.5,
        "main_engine_power": 12.0,
        "side_engine_power": 0.4,
        "initial_x_coeff": 0.4,
    },
    "LowMainEngine": {"main_engine_power": 10.0},
    "LowSideEngine": {"side_engine_power": 0.3, "initial_x_coeff": 0.4},
    "StartRight": {"initial_x_coeff": 0.75},
    # registered by the authors but not in the paper's suite
    "LowGravity": {"gravity": -3.0},
    "StartLow": {"initial_y_coeff": 0.7},
}
_SUITE = ("Default", "HighGravity", "Windy", "Turbulent", "Hard", "LowMainEngine", "LowSideEngine", "StartRight")
OBJECTIVES = ("landing", "shaping", "main_fuel", "side_fuel")

# f_SORL (the paper's appendix): l landing, s shaping, mc / sc main / side engine cost -- the
# vector objectives, so the weights are the formula's coefficients
SORL = SORLReward(
    paper="l + s + 0.3 mc + 0.03 sc",
    weights=(1.0, 1.0, 0.3, 0.03),
    exact=False,
    note="exact on every step but the terminating one: there Gymnasium's reward (the authors' "
         "info['original_scalar_reward']) is replaced by the landing term +-100 alone, while the vector "
         "reward keeps that step's shaping and fuel terms. An episode's f_SORL return is w . R minus the last "
         "step's shaping - 0.3 mc - 0.03 sc (a few units; nothing for an episode cut at 1000 steps).",
)

SPECS = tuple(
    DomainSpec(
        name="MO-LunarLander" + ("-Continuous" if _continuous else ""),
        train_id=f"{_prefix}DR-v0",
        env_class="morl_trl.envs.lunar_lander:MOLunarLanderEnv",
        context_space=LUNAR_LANDER_CONTEXT,
        contexts={f"{_prefix}{k}-v0": v for k, v in _CONTEXTS.items()},
        evaluation_ids=tuple(f"{_prefix}{k}-v0" for k in _SUITE),
        objective_names=OBJECTIVES,
        env_kwargs={"continuous": _continuous},
        gamma=0.99,
        hv_ref_point=(-101.0, -1001.0, -101.0, -101.0),
        max_episode_steps=1000,
        history_len=2,
        train_frames=3_000_000,
        eval_interval=50_000,
        sorl=SORL,
    )
    for _prefix, _continuous in (("MOLunarLander", False), ("MOLunarLanderContinuous", True))
)
