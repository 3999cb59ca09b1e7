"""Draw one MO-LavaGrid grid as an RGB image (MiniGrid's palette)."""

from __future__ import annotations

import numpy as np

__all__ = ["render_grid"]

WALL_RGB = (100, 100, 100)
LAVA_RGB = (255, 128, 0)
GOAL_RGB = ((0, 255, 0), (255, 255, 0), (0, 0, 255))  # goal 0 green, 1 yellow, 2 blue
AGENT_RGB = (255, 0, 0)
LINE_RGB = (60, 60, 60)
COLLECTED_DIM = 0.35


def _agent_mask(tile_size: int, agent_dir: int) -> np.ndarray:
    """A triangle pointing east (MiniGrid's shape), rotated to face ``agent_dir``."""
    c = (np.arange(tile_size) + 0.5) / tile_size
    v, u = np.meshgrid(c, c, indexing="ij")  # v: down (y), u: right (x)
    # vertices (0.12, 0.19), (0.87, 0.50), (0.12, 0.81) in (u, v)
    upper = v >= 0.19 + (0.50 - 0.19) * (u - 0.12) / 0.75
    lower = v <= 0.81 - (0.81 - 0.50) * (u - 0.12) / 0.75
    mask = (u >= 0.12) & upper & lower
    # east -> south -> west -> north is clockwise on screen (y down): rotate clockwise
    return np.rot90(mask, k=-agent_dir)


def render_grid(
    cells: np.ndarray,
    *,
    collected: np.ndarray,
    agent_pos: tuple[int, int],
    agent_dir: int,
    tile_size: int = 16,
) -> np.ndarray:
    """RGB ``uint8`` ``[H * t, W * t, 3]`` of a grid of cell codes indexed ``cells[x, y]``.

    Cell codes: 0 empty, 1 wall, 2 lava, 3 + i goal ``i``.
    """
    if tile_size < 4:
        raise ValueError(f"tile_size must be >= 4 pixels, got {tile_size}")
    palette = np.zeros((6, 3), dtype=np.float32)
    palette[1], palette[2] = WALL_RGB, LAVA_RGB
    for i, rgb in enumerate(GOAL_RGB):
        palette[3 + i] = np.asarray(rgb) * (COLLECTED_DIM if collected[i] else 1.0)
    tiles = palette[cells.T]  # [y, x, 3]: image rows are y
    img = np.repeat(np.repeat(tiles, tile_size, 0), tile_size, 1)
    img[::tile_size, :] = LINE_RGB
    img[:, ::tile_size] = LINE_RGB
    ax, ay = agent_pos
    tile = img[ay * tile_size:(ay + 1) * tile_size, ax * tile_size:(ax + 1) * tile_size]
    tile[_agent_mask(tile_size, agent_dir)] = AGENT_RGB
    return img.astype(np.uint8)
