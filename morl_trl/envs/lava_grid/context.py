"""The MO-LavaGrid context: a map as a float vector, its validation and its randomization.

A context is ``[*B, 93]`` float32, in this order (:data:`CONTEXT_NAMES`):

=========  ========================================================================
entries    meaning
=========  ========================================================================
0..80      the 9x9 interior lava bit map, ``lava_x{x}_y{y}`` for grid cells
           ``x, y in 2..10``, row-major over ``y`` (``bit_map[y - 2][x - 2]``): 1 lava, 0 not
81..86     ``goal{i}_x, goal{i}_y`` for goals ``i = 0, 1, 2`` (grid cells, ``1..11``)
87..89     ``weight{i}``: each goal's reward weight (non-negative, summing to 1)
90..92     ``agent_x, agent_y`` (``1..11``) and ``agent_dir`` (0 east, 1 south, 2 west, 3 north)
=========  ========================================================================

The 13x13 grid around it is fixed: walls at ``x`` or ``y`` in ``{0, 12}`` and lava on the ring
``x`` or ``y`` in ``{1, 11}``. Goals and the agent may sit on the ring (domain randomization
puts them there): a goal replaces the ring lava under it, an agent on the ring stands in lava.

:func:`lava_grid_context` builds a context from ``(layout, goals, weights, start)``,
:func:`parse_lava_map` / :func:`format_lava_map` convert from / to the text format of the
evaluation maps, and :func:`evaluation_maps` loads the eight maps of the paper.
"""

from __future__ import annotations

import functools
from collections.abc import Sequence
from fractions import Fraction
from pathlib import Path

import torch

from morl_trl.envs.context import ContextSpace

__all__ = [
    "CONTEXT_NAMES",
    "LAVA_GRID_CONTEXT",
    "LavaGridContextSpace",
    "evaluation_maps",
    "format_lava_map",
    "lava_grid_context",
    "parse_lava_map",
]

GRID_SIZE = 13
INNER = 11  # the playable 11x11 (ring included), x, y in 1..11
LAYOUT = 9  # the drawn interior, x, y in 2..10
NUM_GOALS = 3
DR_MAX_LAVA = 60  # the authors draw randint(0, 60): 0..59 lava tiles (exclusive bound)

LAVA_SLICE = slice(0, LAYOUT * LAYOUT)
GOALS_SLICE = slice(81, 87)
WEIGHTS_SLICE = slice(87, 90)
AGENT_X, AGENT_Y, AGENT_DIR = 90, 91, 92

CONTEXT_NAMES: tuple[str, ...] = (
    *(f"lava_x{x}_y{y}" for y in range(2, 11) for x in range(2, 11)),
    *(f"goal{i}_{c}" for i in range(NUM_GOALS) for c in ("x", "y")),
    *(f"weight{i}" for i in range(NUM_GOALS)),
    "agent_x",
    "agent_y",
    "agent_dir",
)

DIR_GLYPHS = ">v<^"  # east, south, west, north: MiniGrid's direction order
_MAPS_FILE = Path(__file__).resolve().parents[1] / "data" / "lava_grid_maps.txt"


class LavaGridContextSpace(ContextSpace):
    """The MO-LavaGrid context space (see the module docstring for the layout).

    ``sample`` is the authors' domain randomization, batched: the agent starts uniformly on the
    11x11 playable cells (ring included) except the *previous* episode's goal cells, facing a
    uniform direction; the weights are ``rand(3)`` normalised; three distinct goals are drawn
    uniformly from the cells other than the agent's; then ``k ~ U{0..59}`` lava tiles go on
    distinct cells other than the agent's and the goals' (tiles drawn on the ring change
    nothing, so the 9x9 layout holds at most ``k``).

    ``validate`` also rejects lava bits other than 0/1, cells off the 11x11, goals on interior
    lava, coinciding goals, an agent on a goal, a direction outside 0..3, and weights that are
    negative or do not sum to 1.

    Example:
        >>> import torch
        >>> from morl_trl.envs.lava_grid import LAVA_GRID_CONTEXT
        >>> ctx = LAVA_GRID_CONTEXT.sample(4, generator=torch.Generator().manual_seed(0))
        >>> ctx.shape
        torch.Size([4, 93])
        >>> LAVA_GRID_CONTEXT.validate(ctx, check_range=True).shape
        torch.Size([4, 93])
    """

    def sample(
        self,
        n: int,
        generator: torch.Generator | None = None,
        device: torch.device | str | None = None,
        previous: torch.Tensor | None = None,
    ) -> torch.Tensor:
        """Draw ``n`` randomized maps ``[n, 93]`` (all on ``device``, no host sync).

        ``previous`` (``[n, 93]``, optional) are the contexts of the episodes that just ended:
        as in the authors' code, the new start avoids their goal cells. Without it no cell is
        excluded.
        """
        if generator is not None and device is None:
            device = generator.device
        device = torch.device("cpu") if device is None else torch.device(device)
        cells = INNER * INNER

        def rand(*shape):
            return torch.rand(shape, generator=generator, device=device)

        start_noise = rand(n, cells)
        if previous is not None:
            previous = torch.as_tensor(previous, dtype=torch.float32).to(device)
            if previous.shape != (n, self.dim):
                raise ValueError(f"previous has shape {tuple(previous.shape)}; expected ({n}, {self.dim})")
            start_noise.scatter_(1, _inner_index(previous[:, GOALS_SLICE].reshape(n, NUM_GOALS, 2)), -1.0)
        agent = start_noise.argmax(1)  # uniform over the cells not excluded
        agent_dir = torch.randint(0, 4, (n,), generator=generator, device=device)
        weights = rand(n, NUM_GOALS)
        weights = weights / weights.sum(1, keepdim=True)

        goal_noise = rand(n, cells)
        goal_noise.scatter_(1, agent[:, None], -1.0)
        goals = goal_noise.topk(NUM_GOALS, dim=1).indices  # an ordered uniform draw without replacement

        taken = torch.cat([agent[:, None], goals], 1)
        lava, _ = _draw_lava_cells(taken, generator)
        layout = lava.reshape(n, INNER, INNER)[:, 1:-1, 1:-1]  # [n, x, y] over 2..10
        layout = layout.transpose(1, 2).reshape(n, LAYOUT * LAYOUT)  # row-major over y

        def xy(idx):
            return torch.stack([idx // INNER + 1, idx % INNER + 1], -1).float()

        return torch.cat(
            [
                layout.float(),
                xy(goals).reshape(n, 2 * NUM_GOALS),
                weights,
                xy(agent),
                agent_dir[:, None].float(),
            ],
            1,
        )

    def validate(self, context, *, check_range: bool = False, allow_extrapolation: bool = False) -> torch.Tensor:
        """Check ``[..., 93]`` contexts (see the class docstring); raise ``ValueError`` naming the fault."""
        # the structural checks below imply the declared bounds (and say more): extrapolation
        # beyond them is not a map, so allow_extrapolation changes nothing here
        context = super().validate(context, check_range=check_range, allow_extrapolation=True)
        flat = context.reshape(-1, self.dim)
        lava = flat[:, LAVA_SLICE]
        goals = flat[:, GOALS_SLICE].reshape(-1, NUM_GOALS, 2)
        weights = flat[:, WEIGHTS_SLICE]
        agent = flat[:, AGENT_X:AGENT_Y + 1]
        direction = flat[:, AGENT_DIR]
        cells = torch.cat([goals, agent[:, None]], 1)  # [m, 4, 2]
        on_grid = (cells >= 1) & (cells <= INNER) & (cells == cells.round())
        checks = [
            (((lava == 0) | (lava == 1)).all(1), "lava bits must be 0 or 1"),
            (on_grid.all(-1).all(-1), f"goal and agent cells must be integers in 1..{INNER}"),
            ((direction >= 0) & (direction <= 3) & (direction == direction.round()), "agent_dir must be 0, 1, 2 or 3"),
            ((weights >= 0).all(1), "goal weights must be non-negative"),
            (((weights.sum(1) - 1).abs() <= 1e-4), "goal weights must sum to 1"),
        ]
        g = goals.long().clamp(1, INNER)  # clamped only for indexing; off-grid cells fail above
        same_cell = (g[:, :, None, :] == g[:, None, :, :]).all(-1)
        distinct = ~same_cell | torch.eye(NUM_GOALS, dtype=torch.bool, device=g.device)
        on_layout = ((g >= 2) & (g <= 10)).all(-1)
        lava_idx = ((g[..., 1] - 2) * LAYOUT + (g[..., 0] - 2)).clamp(0, LAYOUT * LAYOUT - 1)
        goal_on_lava = on_layout & (lava.gather(1, lava_idx) == 1)
        agent_on_goal = (goals == agent[:, None, :]).all(-1)
        checks += [
            (distinct.all(-1).all(-1), "the three goals must be on different cells"),
            (~goal_on_lava.any(1), "a goal cannot be on an interior lava tile"),
            (~agent_on_goal.any(1), "the agent cannot start on a goal"),
        ]
        ok = torch.stack([c for c, _ in checks], 0).all(0)
        if not bool(ok.all()):  # one host sync on the happy path; the message costs more
            for valid, message in checks:
                if not bool(valid.all()):
                    row = int((~valid).nonzero()[0])
                    raise ValueError(
                        f"invalid MO-LavaGrid context (row {row}): {message}; got {_describe_row(flat[row])}"
                    )
        return context


def _describe_row(row: torch.Tensor) -> str:
    row = row.detach().cpu()
    goals = [tuple(row[GOALS_SLICE].reshape(3, 2)[i].tolist()) for i in range(NUM_GOALS)]
    lava = row[LAVA_SLICE]
    bad_lava = lava[(lava != 0) & (lava != 1)].tolist()
    return (
        f"goals (x, y) {goals}, weights {row[WEIGHTS_SLICE].tolist()} (sum {float(row[WEIGHTS_SLICE].sum()):g}), "
        f"agent {tuple(row[AGENT_X:AGENT_Y + 1].tolist())} dir {float(row[AGENT_DIR]):g}"
        + (f", non-binary lava bits {bad_lava[:5]}" if bad_lava else "")
    )


def _inner_index(xy: torch.Tensor) -> torch.Tensor:
    """Cells ``(x, y)`` in 1..11 -> x-major index ``(x - 1) * 11 + (y - 1)`` in the 11x11."""
    xy = xy.long()
    return (xy[..., 0] - 1) * INNER + (xy[..., 1] - 1)


def _draw_lava_cells(taken: torch.Tensor, generator: torch.Generator | None) -> tuple[torch.Tensor, torch.Tensor]:
    """Mark ``k ~ U{0..59}`` distinct cells of the 11x11 per row, avoiding the ``taken`` cells.

    Returns the ``[n, 121]`` bool mask (x-major) and ``k`` ``[n]``.
    """
    n, device = taken.shape[0], taken.device
    cells = INNER * INNER
    k = torch.randint(0, DR_MAX_LAVA, (n,), generator=generator, device=device)
    noise = torch.rand((n, cells), generator=generator, device=device)
    noise.scatter_(1, taken, 2.0)  # sorted after every free cell, so never among the first k <= 59 < 117
    order = noise.argsort(1)
    chosen = torch.arange(cells, device=device)[None, :] < k[:, None]
    return torch.zeros(n, cells, dtype=torch.bool, device=device).scatter(1, order, chosen), k


LAVA_GRID_CONTEXT = LavaGridContextSpace(
    names=CONTEXT_NAMES,
    # an open interior, the agent at the authors' default start (2, 2) facing east, goals in
    # the three other corners of the interior with equal weights
    default=(0.0,) * 81 + (10.0, 2.0, 2.0, 10.0, 10.0, 10.0) + (1 / 3,) * 3 + (2.0, 2.0, 0.0),
    low=(0.0,) * 81 + (1.0,) * 6 + (0.0,) * 3 + (1.0, 1.0, 0.0),
    high=(1.0,) * 81 + (float(INNER),) * 6 + (1.0,) * 3 + (float(INNER), float(INNER), 3.0),
    # declared bounds = the grid's own structure (bits 0/1, cells on the 11x11, weights in
    # [0, 1], four directions): domain randomization already covers all of it, and nothing
    # beyond it is a map, so allow_extrapolation keeps the structural checks of `validate`
    valid_low=(0.0,) * 81 + (1.0,) * 6 + (0.0,) * 3 + (1.0, 1.0, 0.0),
    valid_high=(1.0,) * 81 + (float(INNER),) * 6 + (1.0,) * 3 + (float(INNER), float(INNER), 3.0),
)


def lava_grid_context(
    layout,
    goals: Sequence[Sequence[int]],
    weights: Sequence[float],
    agent_pos: Sequence[int] = (2, 2),
    agent_dir: int = 0,
) -> torch.Tensor:
    """Build one validated ``[93]`` context.

    Args:
        layout: the 9x9 interior lava bit map, ``layout[y - 2][x - 2]`` (nested sequences,
            a tensor or an array of 0/1 or bools).
        goals: three ``(x, y)`` cells in 1..11, in goal order 0, 1, 2.
        weights: the three goal weights (non-negative, summing to 1).
        agent_pos: the agent's start ``(x, y)``.
        agent_dir: its facing, 0 east, 1 south, 2 west, 3 north.

    Example:
        >>> layout = [[0] * 9 for _ in range(9)]
        >>> ctx = lava_grid_context(layout, [(4, 2), (6, 2), (8, 2)], [0.5, 0.25, 0.25])
        >>> ctx.shape
        torch.Size([93])
    """
    lay = torch.as_tensor(layout)
    if lay.shape != (LAYOUT, LAYOUT):
        raise ValueError(f"layout has shape {tuple(lay.shape)}; expected ({LAYOUT}, {LAYOUT}) indexed [y - 2][x - 2]")
    goals_t = torch.as_tensor(goals, dtype=torch.float32)
    if goals_t.shape != (NUM_GOALS, 2):
        raise ValueError(f"goals must be {NUM_GOALS} (x, y) pairs, got shape {tuple(goals_t.shape)}")
    weights_t = torch.as_tensor(weights, dtype=torch.float32)
    if weights_t.shape != (NUM_GOALS,):
        raise ValueError(f"weights must have {NUM_GOALS} entries, got shape {tuple(weights_t.shape)}")
    agent_t = torch.as_tensor(agent_pos, dtype=torch.float32)
    if agent_t.shape != (2,):
        raise ValueError(f"agent_pos must be one (x, y) pair, got {agent_pos!r}")
    ctx = torch.cat(
        [lay.float().reshape(-1), goals_t.reshape(-1), weights_t, agent_t, torch.tensor([float(agent_dir)])]
    )
    return LAVA_GRID_CONTEXT.validate(ctx)


def parse_lava_map(rows: Sequence[str] | str, weights: Sequence[float]) -> torch.Tensor:
    """A ``[93]`` context from 9 map rows (the format of ``data/lava_grid_maps.txt``).

    Example:
        >>> rows = [">L...L..0"] + [".........."[:9]] * 7 + ["1.......2"]
        >>> parse_lava_map(rows, [0.2, 0.3, 0.5])[81:]
        tensor([10.0000,  2.0000,  2.0000, 10.0000, 10.0000, 10.0000,  0.2000,  0.3000,
                 0.5000,  2.0000,  2.0000,  0.0000])
    """
    if isinstance(rows, str):
        rows = rows.split()
    rows = list(rows)
    if len(rows) != LAYOUT or any(len(r) != LAYOUT for r in rows):
        raise ValueError(f"a map has {LAYOUT} rows of {LAYOUT} cells; got rows of lengths {[len(r) for r in rows]}")
    layout = [[0] * LAYOUT for _ in range(LAYOUT)]
    goals: dict[int, tuple[int, int]] = {}
    agents = []
    for j, row in enumerate(rows):
        for i, ch in enumerate(row):
            x, y = i + 2, j + 2
            if ch == "L":
                layout[j][i] = 1
            elif ch in "012":
                if int(ch) in goals:
                    raise ValueError(f"goal {ch} appears twice in the map")
                goals[int(ch)] = (x, y)
            elif ch in DIR_GLYPHS:
                agents.append((x, y, DIR_GLYPHS.index(ch)))
            elif ch != ".":
                raise ValueError(
                    f"unknown map cell {ch!r} at (x={x}, y={y}); valid: 'L', '.', '0'-'2', {list(DIR_GLYPHS)}"
                )
    if sorted(goals) != [0, 1, 2]:
        raise ValueError(f"a map needs goals 0, 1 and 2; found {sorted(goals)}")
    if len(agents) != 1:
        raise ValueError(f"a map needs exactly one agent glyph ({DIR_GLYPHS}); found {len(agents)}")
    x, y, d = agents[0]
    return lava_grid_context(layout, [goals[i] for i in range(NUM_GOALS)], weights, (x, y), d)


def format_lava_map(context: torch.Tensor) -> str:
    """The 9 rows of a ``[93]`` context in the map text format (ring cells are not drawn)."""
    ctx = LAVA_GRID_CONTEXT.validate(context).detach().cpu()
    if ctx.ndim != 1:
        raise ValueError(f"format_lava_map takes a single context [93], got {tuple(ctx.shape)}")
    grid = [["L" if b else "." for b in ctx[LAVA_SLICE].reshape(LAYOUT, LAYOUT)[j].tolist()] for j in range(LAYOUT)]
    marks = [(ctx[81 + 2 * i], ctx[82 + 2 * i], str(i)) for i in range(NUM_GOALS)]
    marks.append((ctx[AGENT_X], ctx[AGENT_Y], DIR_GLYPHS[int(ctx[AGENT_DIR])]))
    for x, y, glyph in marks:
        x, y = int(x), int(y)
        if 2 <= x <= 10 and 2 <= y <= 10:
            grid[y - 2][x - 2] = glyph
    return "\n".join("".join(r) for r in grid)


@functools.cache
def _load_maps() -> dict[str, torch.Tensor]:
    maps: dict[str, torch.Tensor] = {}
    name, weights, rows = None, None, []

    def flush():
        if name is not None:
            maps[name] = parse_lava_map(rows, weights)

    for raw in _MAPS_FILE.read_text().splitlines():
        line = raw.split("#", 1)[0].strip()
        if not line:
            continue
        if line.startswith("map "):
            flush()
            name, weights, rows = line.split()[1], None, []
        elif line.startswith("weights "):
            weights = [float(Fraction(w)) for w in line.split()[1:]]
        else:
            rows.append(line)
    flush()
    return maps


def evaluation_maps() -> dict[str, torch.Tensor]:
    """The paper's eight evaluation maps, name -> ``[93]`` context (e.g. ``"Room"``)."""
    return {k: v.clone() for k, v in _load_maps().items()}
