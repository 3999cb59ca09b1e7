"""The stages of MO-SuperMarioBros as a context space (pure torch; loads no emulator).

The context of a sub-env is its stage as the float vector ``[world, level]`` (the paper's
2-D parameter, appendix "MO-SuperMarioBros"), e.g. ``[3., 3.]`` for stage 3-3.
"""

from __future__ import annotations

from dataclasses import dataclass

import torch

from morl_trl.envs.context import ContextSpace

__all__ = [
    "STAGES",
    "HELD_OUT_STAGES",
    "TRAIN_STAGES",
    "EVAL_STAGES",
    "MarioStageSpace",
    "parse_stage",
    "stage_name",
    "MARIO_STAGE_SPACE",
]

STAGES: tuple[tuple[int, int], ...] = tuple((w, l) for w in range(1, 9) for l in range(1, 5))
HELD_OUT_STAGES: tuple[tuple[int, int], ...] = ((3, 3),)  # zero-shot (SPEC §1.4)
TRAIN_STAGES: tuple[tuple[int, int], ...] = tuple(s for s in STAGES if s not in HELD_OUT_STAGES)
EVAL_STAGES: tuple[tuple[int, int], ...] = ((1, 2), (3, 2), (3, 3), (4, 3), (5, 2), (5, 3), (7, 3), (8, 1))


def stage_name(stage) -> str:
    """``(3, 3)`` or ``tensor([3., 3.])`` -> ``"3-3"``."""
    world, level = (int(v) for v in stage)
    return f"{world}-{level}"


def parse_stage(name: str) -> tuple[int, int]:
    """``"3-3"`` -> ``(3, 3)``; a ``ValueError`` lists the valid stages otherwise."""
    try:
        world, level = (int(part) for part in str(name).split("-"))
    except ValueError:
        world = level = None
    if (world, level) not in STAGES:
        raise ValueError(f"unknown stage {name!r}; valid stages: {', '.join(map(stage_name, STAGES))}")
    return world, level


@dataclass(frozen=True, repr=False)
class MarioStageSpace(ContextSpace):
    """Stages ``[world, level]`` of Super Mario Bros.; domain randomization draws uniformly
    among ``train_stages`` (all 32 but the held-out 3-3 by default).

    ``validate`` accepts any of the 32 stages (3-3 is a valid evaluation context) and raises
    a ``ValueError`` listing them for anything else.

    Example:
        >>> import torch
        >>> space = MarioStageSpace()
        >>> space.make(world=3, level=3)
        tensor([3., 3.])
        >>> ctx = space.sample(1000, generator=torch.Generator().manual_seed(0))
        >>> bool(((ctx[:, 0] == 3) & (ctx[:, 1] == 3)).any())
        False
    """

    names: tuple[str, ...] = ("world", "level")
    default: tuple[float, ...] = (1.0, 1.0)
    low: tuple[float, ...] = (1.0, 1.0)
    high: tuple[float, ...] = (8.0, 4.0)
    # declared bounds = the game's structure: worlds 1..8, levels 1..4 (validate requires one
    # of the 32 stages, with or without allow_extrapolation: there is nothing in between)
    valid_low: tuple[float, ...] | None = (1.0, 1.0)
    valid_high: tuple[float, ...] | None = (8.0, 4.0)
    train_stages: tuple[tuple[int, int], ...] = TRAIN_STAGES

    def __post_init__(self) -> None:
        super().__post_init__()
        train = tuple((int(w), int(l)) for w, l in self.train_stages)
        unknown = [s for s in train if s not in STAGES]
        if unknown or not train:
            raise ValueError(
                f"train_stages must be a non-empty subset of the 32 stages; unknown: {[stage_name(s) for s in unknown]}"
            )
        object.__setattr__(self, "train_stages", train)

    def sample(self, n: int, generator: torch.Generator | None = None, device=None) -> torch.Tensor:
        """Draw ``n`` stages uniformly from ``train_stages`` as ``[n, 2]`` floats."""
        if generator is not None and device is None:
            device = generator.device
        table = torch.tensor(self.train_stages, dtype=torch.float32, device=device)
        pick = torch.randint(len(self.train_stages), (n,), generator=generator, device=device)
        return table[pick]

    def validate(self, context, *, check_range: bool = False, allow_extrapolation: bool = False) -> torch.Tensor:
        # the stage check below implies the declared bounds (and lists the valid stages):
        # there is no stage to extrapolate to, so allow_extrapolation changes nothing here
        context = super().validate(context, check_range=check_range, allow_extrapolation=True)
        flat = context.reshape(-1, 2)
        valid = torch.tensor(STAGES, dtype=flat.dtype, device=flat.device)
        ok = (flat[:, None, :] == valid[None]).all(-1).any(-1)
        if not ok.all():
            row = int((~ok).nonzero()[0])
            w, l = flat[row].tolist()
            raise ValueError(
                f"context [world={w:g}, level={l:g}] (row {row}) is not a stage; valid stages "
                f"[world, level]: {', '.join(map(stage_name, STAGES))}"
            )
        return context

    def __repr__(self) -> str:
        held_out = [stage_name(s) for s in STAGES if s not in self.train_stages]
        return (
            f"MarioStageSpace(world in 1..8, level in 1..4; {len(self.train_stages)} training stages, "
            f"held out: {', '.join(held_out) or 'none'})"
        )

    def stage(self, name: str) -> torch.Tensor:
        """The context of a stage given by name, e.g. ``space.stage("3-3")``."""
        return torch.tensor(parse_stage(name), dtype=torch.float32)


MARIO_STAGE_SPACE = MarioStageSpace()
