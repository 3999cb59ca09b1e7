"""Running the *upstream* gym-super-mario-bros 7.4.0 environment on NumPy 2 (for comparisons).

Our domain does not use it (see :mod:`morl_trl.envs.mario._nes`); the benchmark measures it
as the peer and a test checks our game logic against it frame by frame. Two things stand
in the way, and both are handled here, only when :func:`load_upstream` is called:

* importing it imports the old ``gym`` package, which prints a deprecation banner to stderr
  and sets ``SDL_AUDIODRIVER``/``PYGAME_HIDE_SUPPORT_PROMPT`` for the whole process. We
  silence the banner during that import and restore the environment variables after it.
* NumPy 2 (NEP 50) keeps ``uint8`` scalars ``uint8`` in arithmetic with Python ints, so three
  upstream expressions overflow: ``ROM.prg_rom_size * 2**10`` and ``ROM.chr_rom_size *
  2**10`` (the header sizes, an ``OverflowError`` before the game even starts) and
  ``SuperMarioBrosEnv._x_position = ram[0x6d] * 0x100 + ram[0x86]``. :func:`numpy2_shim`
  replaces the two ROM properties by int-typed ones (same values; applied once, in memory,
  nothing in site-packages changes), and :func:`upstream_stage_env` returns a subclass of
  ``SuperMarioBrosEnv`` whose ``_x_position`` uses ints.
"""

from __future__ import annotations

import contextlib
import importlib
import io
import os
import warnings

__all__ = ["load_upstream", "numpy2_shim", "upstream_stage_env"]

_ENV_VARS = ("SDL_AUDIODRIVER", "PYGAME_HIDE_SUPPORT_PROMPT")
_SHIMMED = False


@contextlib.contextmanager
def _quiet_gym_import():
    saved = {k: os.environ.get(k) for k in _ENV_VARS}
    try:
        with contextlib.redirect_stderr(io.StringIO()), warnings.catch_warnings():
            warnings.simplefilter("ignore")
            yield
    finally:
        for k, v in saved.items():
            if v is None:
                os.environ.pop(k, None)
            else:
                os.environ[k] = v


def _int_rom_sizes(rom_cls) -> None:
    rom_cls.prg_rom_size = property(lambda self: 16 * int(self.header[4]))
    rom_cls.chr_rom_size = property(lambda self: 8 * int(self.header[5]))


def numpy2_shim() -> None:
    """Make nes-py's ``ROM`` header sizes Python ints (idempotent)."""
    global _SHIMMED
    if _SHIMMED:
        return
    with _quiet_gym_import():
        rom_module = importlib.import_module("nes_py._rom")
    _int_rom_sizes(rom_module.ROM)
    _SHIMMED = True


def load_upstream():
    """Import ``gym_super_mario_bros`` quietly, with the NumPy-2 shim applied; returns the module."""
    numpy2_shim()
    with _quiet_gym_import():
        return importlib.import_module("gym_super_mario_bros")


def upstream_stage_env(world: int, level: int, rom_mode: str = "pixel"):
    """The upstream single-stage ``SuperMarioBrosEnv`` (old-gym API), fixed for NumPy 2."""
    smb = load_upstream()

    class NumPy2SuperMarioBrosEnv(smb.SuperMarioBrosEnv):
        @property
        def _x_position(self):
            return int(self.ram[0x6D]) * 0x100 + int(self.ram[0x86])

    return NumPy2SuperMarioBrosEnv(rom_mode=rom_mode, target=(int(world), int(level)))
