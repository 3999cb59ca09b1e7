"""Super Mario Bros. game logic on top of the emulator: stage start, per-frame rewards, skips.

This reproduces what ``gym_super_mario_bros.SuperMarioBrosEnv`` (7.4.0) does for a
single-stage environment (``target=(world, level)``), reading the RAM as Python ints:

* start: press *start* on the title screen while writing the target world/level/area into
  RAM, run out the pre-level timer, idle until the in-game clock ticks, then snapshot; a
  reset restores the snapshot;
* per frame: the episode ends when Mario is dying (state ``0x0B`` or below the viewport),
  dead (state ``0x06``) or reaches the flag / axe; otherwise the area-change timer and the
  "busy" states (pipes, auto-walk, the black screen) are fast-forwarded within the frame;
* the MO-SuperMarioBros reward of SPEC §1.4, per raw frame, from RAM deltas.

RAM addresses (https://datacrystal.tcrf.net/wiki/Super_Mario_Bros.:RAM_map): x =
``0x6D * 256 + 0x86``; timer BCD ``0x7F8`` (3 digits); coins BCD ``0x7ED`` (2); score BCD
``0x7DE`` (6); lives ``0x75A``; player state ``0x0E``; vertical viewport ``0xB5``.
"""

from __future__ import annotations

from dataclasses import dataclass

from morl_trl.envs.mario._nes import NESEmulator, rom_path

__all__ = [
    "SIMPLE_MOVEMENT",
    "SIMPLE_MOVEMENT_BUTTONS",
    "MarioStage",
    "FrameOutcome",
    "x_position",
    "read_bcd",
    "stage_area",
]

# Controller bitmap: right, left, down, up, start, select, B, A (MSB to LSB).
_BUTTON = {"right": 0x80, "left": 0x40, "down": 0x20, "up": 0x10, "start": 0x08, "select": 0x04, "B": 0x02, "A": 0x01}
SIMPLE_MOVEMENT: tuple[tuple[str, ...], ...] = (
    ("NOOP",),
    ("right",),
    ("right", "A"),
    ("right", "B"),
    ("right", "A", "B"),
    ("A",),
    ("left",),
)
SIMPLE_MOVEMENT_BUTTONS: tuple[int, ...] = tuple(
    sum(_BUTTON.get(b, 0) for b in combo) for combo in SIMPLE_MOVEMENT
)

_START = _BUTTON["start"]
_BUSY_STATES = frozenset({0x00, 0x01, 0x02, 0x03, 0x04, 0x05, 0x07})
_ENEMY_TYPE_ADDRESSES = (0x16, 0x17, 0x18, 0x19, 0x1A)
_STAGE_OVER_ENEMIES = frozenset({0x2D, 0x31})  # Bowser, flagpole

# SPEC §1.4: penalties are added to every objective, then everything is scaled by 3/100.
# FrameOutcome.death reports -25 on the frame Mario starts dying (gym-super-mario-bros' own death
# penalty, part of original_reward); the vector reward adds it only with the env's
# death_penalty_on_dying=True (the authors' episode ends before their "lives dropped" -25 fires).
DEATH_PENALTY = -25.0
REWARD_SCALE = 3 / 100
X_REWARD_FLOOR = -5  # a larger backwards jump of x is a position reset, not movement


def read_bcd(ram, address: int, digits: int) -> int:
    """A decimal number stored one digit per byte (score, coins, timer)."""
    value = 0
    for d in ram[address : address + digits]:
        value = value * 10 + int(d)  # int(): RAM may be a uint8 NumPy array
    return value


def x_position(ram) -> int:
    """Mario's horizontal position in the stage: page ``0x6D`` * 256 + pixel ``0x86``.

    (gym-super-mario-bros computes this on ``uint8`` NumPy scalars, which overflows under
    NumPy 2; on ctypes items or Python ints it is exact.)
    """
    return int(ram[0x6D]) * 0x100 + int(ram[0x86])


def stage_area(world: int, level: int) -> int:
    """The area number the ROM uses for ``world-level`` (worlds 1, 2, 4, 7 have an extra
    pipe-intro area before levels 2-4)."""
    return level + 1 if world in (1, 2, 4, 7) and level >= 2 else level


@dataclass
class FrameOutcome:
    """Rewards of one raw frame, before scaling: ``x``, ``time``, ``death``, ``coin``, ``enemy``."""

    x: float
    time: float
    death: float
    coin: float
    enemy: float
    done: bool
    flag: bool


class MarioStage:
    """One emulator running one stage, restartable in a few microseconds.

    Args:
        world, level: the stage (1-8, 1-4).
        rom_mode: which shipped ROM to use (the benchmark uses ``"pixel"``).

    Example:
        >>> stage = MarioStage(1, 1)                    # doctest: +SKIP
        >>> stage.reset(); stage.frame(SIMPLE_MOVEMENT_BUTTONS[1]).x   # doctest: +SKIP
        40.0
    """

    def __init__(self, world: int, level: int, rom_mode: str = "pixel") -> None:
        self.world, self.level = int(world), int(level)
        self.nes = NESEmulator(rom_path(rom_mode))
        self.ram = self.nes.ram
        self._start_stage()
        self.nes.backup()
        self.reset()

    # ------------------------------------------------------------------ RAM views
    @property
    def time(self) -> int:
        return read_bcd(self.ram, 0x7F8, 3)

    @property
    def coins(self) -> int:
        return read_bcd(self.ram, 0x7ED, 2)

    @property
    def score(self) -> int:
        return read_bcd(self.ram, 0x7DE, 6)

    @property
    def lives(self) -> int:
        return self.ram[0x75A]

    @property
    def x(self) -> int:
        return x_position(self.ram)

    @property
    def is_dying(self) -> bool:
        return self.ram[0x0E] == 0x0B or self.ram[0xB5] > 1

    @property
    def is_dead(self) -> bool:
        return self.ram[0x0E] == 0x06

    @property
    def flag_get(self) -> bool:
        ram = self.ram
        if ram[0x770] == 2:  # end of world
            return True
        for address in _ENEMY_TYPE_ADDRESSES:
            if ram[address] in _STAGE_OVER_ENEMIES:
                return ram[0x1D] == 3  # sliding down the pole (not climbing a vine)
        return False

    def loaded_stage(self) -> tuple[int, int]:
        """The (world, level) the game is currently in, from RAM."""
        return self.ram[0x75F] + 1, self.ram[0x75C] + 1

    # ------------------------------------------------------------------ control
    def _start_stage(self) -> None:
        nes, ram = self.nes, self.ram
        area = stage_area(self.world, self.level)
        nes.step(_START)
        nes.step(0)
        while self.time == 0:
            nes.step(_START)
            ram[0x75F], ram[0x75C], ram[0x760] = self.world - 1, self.level - 1, area - 1
            nes.step(0)
            ram[0x7A0] = 0  # run out the pre-level timer
        last = self.time
        while self.time >= last:  # idle until the clock ticks, as gym-super-mario-bros does
            last = self.time
            nes.step(_START)
            nes.step(0)
        if self.loaded_stage() != (self.world, self.level):
            raise RuntimeError(f"stage {self.world}-{self.level} did not load (got {self.loaded_stage()})")

    def reset(self) -> None:
        """Back to the start of the stage; the reward trackers restart from zero (SPEC §1.4:
        x, coins, time and score start at 0, so the first frame earns the start x as progress)."""
        self.nes.restore()
        self._x = self._time = self._coins = self._score = 0
        self.done = False

    def frame(self, buttons: int) -> FrameOutcome:
        """Advance one raw frame holding ``buttons`` and return its rewards."""
        nes, ram = self.nes, self.ram
        nes.step(buttons)
        x, t, c, s = self.x, self.time, self.coins, self.score
        dying = self.is_dying or self.is_dead
        flag = self.flag_get
        done = dying or flag
        dx, self._x = x - self._x, x
        if dx < X_REWARD_FLOOR:
            dx = 0
        dt, self._time = t - self._time, t
        if dt > 0:
            dt = 0  # the clock only counts down; an increase is the reset
        coin, self._coins = 100 * (c - self._coins), c
        enemy, self._score = (s - self._score) - 2 * coin, s  # a coin is worth 200 points
        if enemy < 0 or done:
            enemy = 0
        death = DEATH_PENALTY if dying else 0.0
        self.done = done
        if not done:
            change_area_timer = ram[0x6DE]
            if 1 < change_area_timer < 255:
                ram[0x6DE] = 1
            while ram[0x0E] in _BUSY_STATES or ram[0x770] == 2:
                ram[0x7A0] = 0
                nes.step(0)
        return FrameOutcome(float(dx), float(dt), death, float(coin), float(enemy), done, flag)

    def close(self) -> None:
        self.nes.close()
