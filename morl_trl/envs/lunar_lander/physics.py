"""One MO-LunarLander Box2D world: Gymnasium's constants, terrain, lander and legs.

The numbers and the order of the random draws follow Gymnasium's ``LunarLander-v3``
(``gymnasium/envs/box2d/lunar_lander.py``), so that a world built from the same generator
state is the same world. What the context changes (SPEC §1.1): the world's gravity and the
spawn point ``(VIEWPORT_W / SCALE * x_coeff, VIEWPORT_H / SCALE * y_coeff)``. Exhaust
particles are not modelled: they are rendering-only bodies that collide only with the
ground, so they never touch the lander's island.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from Box2D import _Box2D, b2_dynamicBody, b2_staticBody, b2BodyDef, b2World
from Box2D.b2 import contactListener, edgeShape, fixtureDef, polygonShape, revoluteJointDef

FPS = 50
SCALE = 30.0
INITIAL_RANDOM = 1000.0
LANDER_POLY = ((-14, +17), (-17, 0), (-17, -10), (+17, -10), (+17, 0), (+14, +17))
LEG_AWAY = 20
LEG_DOWN = 18
LEG_W, LEG_H = 2, 8
LEG_SPRING_TORQUE = 40
SIDE_ENGINE_HEIGHT = 14
SIDE_ENGINE_AWAY = 12
MAIN_ENGINE_Y_LOCATION = 4
VIEWPORT_W = 600
VIEWPORT_H = 400
W = VIEWPORT_W / SCALE
H = VIEWPORT_H / SCALE
CHUNKS = 11
HELIPAD_Y = H / 4
TIME_STEP = 1.0 / FPS
VELOCITY_ITERATIONS = 6 * 30
POSITION_ITERATIONS = 2 * 30
WIND_K1 = 0.02  # wind/torque index -> tanh(sin(0.02 k) + sin(pi * 0.01 k))
WIND_K2 = math.pi * 0.01

LANDER = "lander"  # userData tags read by the contact listener; the legs are tagged 0 and 1


class ContactFlags(contactListener):
    """Writes Gymnasium's contact flags of sub-env ``index`` into shared numpy arrays.

    ``game_over[index]`` latches when the lander body touches anything (the ground: it
    collides with nothing else); ``legs[index, j]`` follows the begin/end contact events of
    leg ``j``, exactly as Gymnasium's ``ContactDetector``.
    """

    def __init__(self, game_over: np.ndarray, legs: np.ndarray, index: int) -> None:
        super().__init__()
        self.game_over = game_over
        self.legs = legs
        self.index = index

    def BeginContact(self, contact):  # noqa: N802 (Box2D's name)
        a, b = contact.fixtureA.body.userData, contact.fixtureB.body.userData
        if a == LANDER or b == LANDER:
            self.game_over[self.index] = True
        for j in (0, 1):
            if a == j or b == j:
                self.legs[self.index, j] = True

    def EndContact(self, contact):  # noqa: N802
        a, b = contact.fixtureA.body.userData, contact.fixtureB.body.userData
        for j in (0, 1):
            if a == j or b == j:
                self.legs[self.index, j] = False


@dataclass
class LanderWorld:
    """The Box2D objects of one sub-env (and what rendering needs)."""

    world: b2World
    lander: object
    legs: tuple
    sky_polys: list
    wind_idx: int
    torque_idx: int


# pybox2d's C entry points behind world.CreateBody, body.CreateFixture, world.CreateJoint and
# edge.vertices: its Python wrappers only check and forward the definitions built below
_create_body = _Box2D.b2World___CreateBody
_create_fixture = _Box2D.b2Body___CreateFixture
_create_joint = _Box2D.b2World___CreateJoint
_set_vertex1, _set_vertex2 = _Box2D.b2EdgeShape_vertex1_set, _Box2D.b2EdgeShape_vertex2_set


def _fixture(shape, **kwargs) -> fixtureDef:
    fixture = fixtureDef(shape=shape, **kwargs)
    fixture.keep_shape = shape  # the definition points into the shape: keep it alive
    return fixture


# Definitions reused by every build (Box2D copies them into the world), set up once instead
# of through pybox2d's keyword constructors: the same values, a fraction of the time.
_GROUND = b2BodyDef(type=b2_staticBody)
_BASE_EDGE = _fixture(edgeShape(vertices=[(0, 0), (W, 0)]))
_TERRAIN_EDGE = _fixture(edgeShape(vertices=[(0, 0), (1, 0)]), density=0, friction=0.1)
_LANDER_FIXTURE = _fixture(
    polygonShape(vertices=[(x / SCALE, y / SCALE) for x, y in LANDER_POLY]),
    density=5.0, friction=0.1, categoryBits=0x0010, maskBits=0x001, restitution=0.0,
)
_LEG_FIXTURE = _fixture(
    polygonShape(box=(LEG_W / SCALE, LEG_H / SCALE)),
    density=1.0, restitution=0.0, categoryBits=0x0020, maskBits=0x001,
)
_BODY = b2BodyDef(type=b2_dynamicBody)
_LEG_JOINTS = []
for _side in (-1, +1):
    _rjd = revoluteJointDef(
        localAnchorA=(0, 0),
        localAnchorB=(_side * LEG_AWAY / SCALE, LEG_DOWN / SCALE),
        enableMotor=True,
        enableLimit=True,
        maxMotorTorque=LEG_SPRING_TORQUE,
        motorSpeed=+0.3 * _side,
    )
    _rjd.lowerAngle, _rjd.upperAngle = (+0.9 - 0.5, +0.9) if _side == -1 else (-0.9, -0.9 + 0.5)
    _LEG_JOINTS.append(_rjd)


def build_world(
    rng: np.random.Generator,
    gravity: float,
    x_coeff: float,
    y_coeff: float,
    listener: ContactFlags,
) -> LanderWorld:
    """Create a fresh world as Gymnasium's ``reset`` does (without its closing no-op step).

    Draws from ``rng`` in Gymnasium's order: 12 terrain heights, the 2 components of the
    initial push, then the wind and torque indices (``enable_wind`` is always on). Bodies,
    fixtures and joints are created in Gymnasium's order with Gymnasium's values.
    """
    world = b2World(gravity=(0, gravity))
    world.contactListener = listener

    height = rng.uniform(0, H / 2, size=(CHUNKS + 1,))
    chunk_x = [W / (CHUNKS - 1) * i for i in range(CHUNKS)]
    height[CHUNKS // 2 - 2 : CHUNKS // 2 + 3] = HELIPAD_Y
    i = np.arange(CHUNKS)
    smooth_y = (0.33 * (height[i - 1] + height[i] + height[i + 1])).tolist()  # i-1 wraps at 0, as in Gymnasium

    moon = _create_body(world, _GROUND)
    _create_fixture(moon, _BASE_EDGE)
    edge = _TERRAIN_EDGE.keep_shape  # a two-vertex edge: only its two vertices change
    sky_polys = []
    for k in range(CHUNKS - 1):
        p1 = (chunk_x[k], smooth_y[k])
        p2 = (chunk_x[k + 1], smooth_y[k + 1])
        _set_vertex1(edge, p1)
        _set_vertex2(edge, p2)
        _create_fixture(moon, _TERRAIN_EDGE)
        sky_polys.append([p1, p2, (p2[0], H), (p1[0], H)])

    initial_x = VIEWPORT_W / SCALE * x_coeff
    initial_y = VIEWPORT_H / SCALE * y_coeff
    _BODY.position = (initial_x, initial_y)
    _BODY.angle = 0.0
    lander = _create_body(world, _BODY)
    _create_fixture(lander, _LANDER_FIXTURE)
    lander.userData = LANDER
    push = (rng.uniform(-INITIAL_RANDOM, INITIAL_RANDOM), rng.uniform(-INITIAL_RANDOM, INITIAL_RANDOM))
    lander.ApplyForceToCenter(push, True)
    wind_idx = int(rng.integers(-9999, 9999))
    torque_idx = int(rng.integers(-9999, 9999))

    legs = []
    for j, (side, rjd) in enumerate(zip((-1, +1), _LEG_JOINTS)):
        _BODY.position = (initial_x - side * LEG_AWAY / SCALE, initial_y)
        _BODY.angle = side * 0.05
        leg = _create_body(world, _BODY)
        _create_fixture(leg, _LEG_FIXTURE)
        leg.userData = j
        rjd.bodyA, rjd.bodyB = lander, leg
        rjd.referenceAngle = leg.angle - lander.angle  # as pybox2d's revoluteJointDef(bodyA=, bodyB=)
        _create_joint(world, rjd)
        legs.append(leg)
    for rjd in _LEG_JOINTS:  # no references from the module-level definitions into this world
        rjd.bodyA = rjd.bodyB = None
    return LanderWorld(world, lander, tuple(legs), sky_polys, wind_idx, torque_idx)
