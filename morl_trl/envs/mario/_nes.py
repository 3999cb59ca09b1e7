"""A thin ctypes binding to nes-py's emulator core, loaded without nes-py's Python layer.

``nes_py/__init__.py`` imports the unmaintained ``gym`` package, which prints a banner, sets
``SDL_AUDIODRIVER`` for the whole process, and whose ROM/RAM helpers overflow ``uint8``
arithmetic under NumPy 2. The emulator itself is a small C library (``lib_nes_env*.so``)
with nine entry points; we locate it with :func:`importlib.util.find_spec` (which does not
execute the package) and call it directly. RAM is exposed as a ``ctypes`` byte array, whose
items are plain Python ints, so every address arithmetic is exact whatever NumPy does.

The ROMs come from ``gym_super_mario_bros/_roms`` (also located without importing it).
"""

from __future__ import annotations

import ctypes
import functools
import glob
import importlib.util
import os
import sys
from dataclasses import dataclass

import numpy as np

__all__ = ["require_emulator", "NESEmulator", "RomHeader", "read_rom_header", "rom_path", "SCREEN_HEIGHT", "SCREEN_WIDTH", "RGB_CHANNELS"]

SCREEN_HEIGHT = 240
SCREEN_WIDTH = 256
RAM_SIZE = 0x800
# The core writes 32-bit pixels; byte order B, G, R, x on a little-endian machine.
RGB_CHANNELS = (2, 1, 0) if sys.byteorder == "little" else (1, 2, 3)

_MISSING = (
    "MO-SuperMarioBros needs the NES emulator: pip install 'morl-trl[mario]' "
    "(gym-super-mario-bros==7.4.0, nes-py==8.2.1)"
)


def _package_dir(name: str) -> str:
    """The directory of an installed package, found without importing it."""
    spec = importlib.util.find_spec(name)
    if spec is None or not spec.submodule_search_locations:
        raise ModuleNotFoundError(f"{name} is not installed. {_MISSING}", name=name)
    return list(spec.submodule_search_locations)[0]


def require_emulator() -> None:
    """Raise ``ModuleNotFoundError`` (an ``ImportError``) naming the ``mario`` extra when
    nes-py or gym-super-mario-bros is not installed; imports neither."""
    for name in ("nes_py", "gym_super_mario_bros"):
        _package_dir(name)


@functools.cache
def _library() -> ctypes.CDLL:
    """Load ``lib_nes_env`` once and declare the signatures of its entry points."""
    candidates = glob.glob(os.path.join(_package_dir("nes_py"), "lib_nes_env*"))
    if not candidates:
        raise ModuleNotFoundError(f"nes_py has no compiled lib_nes_env library. {_MISSING}", name="nes_py")
    lib = ctypes.cdll.LoadLibrary(candidates[0])  # CDLL: calls release the GIL
    ptr = ctypes.c_void_p
    signatures = {
        "Width": ([], ctypes.c_uint),
        "Height": ([], ctypes.c_uint),
        "Initialize": ([ctypes.c_wchar_p], ptr),
        "Controller": ([ptr, ctypes.c_uint], ptr),
        "Screen": ([ptr], ptr),
        "Memory": ([ptr], ptr),
        "Reset": ([ptr], None),
        "Step": ([ptr], None),
        "Backup": ([ptr], None),
        "Restore": ([ptr], None),
        "Close": ([ptr], None),
    }
    for name, (args, res) in signatures.items():
        fn = getattr(lib, name)
        fn.argtypes = args
        fn.restype = res
    if (lib.Width(), lib.Height()) != (SCREEN_WIDTH, SCREEN_HEIGHT):
        raise RuntimeError(f"unexpected NES screen size {lib.Width()}x{lib.Height()}")
    return lib


def rom_path(mode: str = "pixel") -> str:
    """Path of a Super Mario Bros. ROM shipped with gym-super-mario-bros.

    ``mode`` is one of ``"vanilla"``, ``"pixel"``, ``"rectangle"``, ``"downsample"``.
    """
    modes = ("vanilla", "pixel", "rectangle", "downsample")
    if mode not in modes:
        raise ValueError(f"unknown ROM mode {mode!r}; valid modes: {list(modes)}")
    name = "super-mario-bros.nes" if mode == "vanilla" else f"super-mario-bros-{mode}.nes"
    path = os.path.join(_package_dir("gym_super_mario_bros"), "_roms", name)
    if not os.path.isfile(path):
        raise FileNotFoundError(f"ROM {path} not found. {_MISSING}")
    return path


@dataclass(frozen=True)
class RomHeader:
    """The iNES header fields the emulator relies on, as Python ints."""

    prg_rom_kb: int
    chr_rom_kb: int
    mapper: int
    has_trainer: bool
    is_pal: bool

    @property
    def prg_rom_bytes(self) -> int:
        return self.prg_rom_kb * 1024

    @property
    def chr_rom_bytes(self) -> int:
        return self.chr_rom_kb * 1024


def read_rom_header(path: str) -> RomHeader:
    """Parse and check an iNES header with Python ints.

    nes-py's ``ROM`` class computes ``16 * header[4] * 2**10`` on a ``uint8`` array, which
    NumPy 2 rejects (``OverflowError``); here every byte is converted with ``int`` first.
    """
    with open(path, "rb") as f:
        header = f.read(16)
    if len(header) < 16 or header[:4] != b"NES\x1a":
        raise ValueError(f"{path} is not an iNES ROM (missing the 'NES<EOF>' magic number)")
    h = list(header)  # bytes -> Python ints
    info = RomHeader(
        prg_rom_kb=16 * h[4],
        chr_rom_kb=8 * h[5],
        mapper=(h[7] & 0xF0) | (h[6] >> 4),
        has_trainer=bool(h[6] & 0x04),
        is_pal=bool(h[9] & 0x01),
    )
    size = os.path.getsize(path)
    if info.prg_rom_kb == 0 or info.has_trainer or info.is_pal or info.mapper not in (0, 1, 2, 3):
        raise ValueError(f"{path}: unsupported ROM ({info})")
    if 16 + info.prg_rom_bytes + info.chr_rom_bytes > size:
        raise ValueError(f"{path}: file is shorter than its header announces ({info}, {size} bytes)")
    return info


class NESEmulator:
    """One NES: controller, one frame per :meth:`step`, RAM and screen as live views.

    Attributes:
        ram: ``ctypes`` array of the 2 KiB work RAM (items are Python ints; writable).
        screen: ``uint8`` NumPy view ``[240, 256, 4]`` of the frame buffer (channel order
            :data:`RGB_CHANNELS`).
    """

    def __init__(self, path: str) -> None:
        read_rom_header(path)  # the C++ core does not validate ROMs
        self._lib = _library()
        self._env = self._lib.Initialize(path)
        if not self._env:
            raise RuntimeError(f"nes-py could not load {path}")
        self.ram = (ctypes.c_uint8 * RAM_SIZE).from_address(self._lib.Memory(self._env))
        self._pad = (ctypes.c_uint8 * 1).from_address(self._lib.Controller(self._env, 0))
        nbytes = SCREEN_HEIGHT * SCREEN_WIDTH * 4
        buf = (ctypes.c_uint8 * nbytes).from_address(self._lib.Screen(self._env))
        self.screen = np.frombuffer(buf, dtype=np.uint8).reshape(SCREEN_HEIGHT, SCREEN_WIDTH, 4)
        self._lib.Reset(self._env)

    def step(self, buttons: int = 0) -> None:
        """Hold the controller ``buttons`` (a bitmap) and advance one frame."""
        self._pad[0] = buttons
        self._lib.Step(self._env)

    def backup(self) -> None:
        """Snapshot the machine state (one slot)."""
        self._lib.Backup(self._env)

    def restore(self) -> None:
        """Return to the snapshot taken by :meth:`backup`."""
        self._lib.Restore(self._env)

    def rgb(self) -> np.ndarray:
        """A copy of the current frame as ``uint8 [240, 256, 3]`` RGB."""
        return self.screen[:, :, list(RGB_CHANNELS)].copy()

    def close(self) -> None:
        if self._env is not None:
            self._lib.Close(self._env)
            self._env = None

    def __del__(self) -> None:  # pragma: no cover - best effort at interpreter exit
        try:
            self.close()
        except Exception:
            pass
