"""Draw one LunarLander world to an RGB array with Pillow (no window, no pygame).

The picture follows Gymnasium's: white ground, black sky, the lander and legs in purple,
two yellow flags at the helipad. Exhaust particles are not drawn (they are not simulated).
"""

from __future__ import annotations

import numpy as np

from morl_trl.envs.lunar_lander.physics import HELIPAD_Y, SCALE, VIEWPORT_H, VIEWPORT_W, W, CHUNKS, LanderWorld

_BODY_FILL = (128, 102, 230)
_BODY_EDGE = (77, 77, 128)
_FLAG = (204, 204, 0)


def render_world(world: LanderWorld) -> np.ndarray:
    """The ``[VIEWPORT_H, VIEWPORT_W, 3]`` ``uint8`` image of ``world``."""
    from PIL import Image, ImageDraw

    img = Image.new("RGB", (VIEWPORT_W, VIEWPORT_H), (255, 255, 255))
    draw = ImageDraw.Draw(img)
    for poly in world.sky_polys:
        draw.polygon([(x * SCALE, y * SCALE) for x, y in poly], fill=(0, 0, 0))
    for body in (world.lander, *world.legs):
        for fixture in body.fixtures:
            transform = body.transform
            path = [tuple(transform * v * SCALE) for v in fixture.shape.vertices]
            draw.polygon(path, fill=_BODY_FILL, outline=_BODY_EDGE)
    for chunk in (CHUNKS // 2 - 1, CHUNKS // 2 + 1):
        x = W / (CHUNKS - 1) * chunk * SCALE
        y1 = HELIPAD_Y * SCALE
        y2 = y1 + 50
        draw.line([(x, y1), (x, y2)], fill=(255, 255, 255), width=1)
        draw.polygon([(x, y2), (x, y2 - 10), (x + 25, y2 - 5)], fill=_FLAG)
    # Box2D's y axis points up, the image's down
    return np.ascontiguousarray(np.asarray(img)[::-1])
