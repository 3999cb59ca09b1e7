"""glibc's allocator set for training (:mod:`morl_trl.training.allocator`): a large block freed by one update
stays in the heap for the next (no unmapping and re-faulting), and the switch that turns it off."""

import json
import os
import platform
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]

pytestmark = pytest.mark.skipif(not sys.platform.startswith("linux") or platform.libc_ver()[0] != "glibc",
                                reason="glibc only")

# in a fresh process: tune_malloc(), then malloc / touch / free one 8 MiB block, reading glibc's mallinfo2
PROBE = r"""
import ctypes, importlib.util, json, sys
spec = importlib.util.spec_from_file_location("allocator", sys.argv[1])  # (the module alone: no package import)
allocator = importlib.util.module_from_spec(spec)
spec.loader.exec_module(allocator)
tune_malloc = allocator.tune_malloc
class Info(ctypes.Structure):
    _fields_ = [(n, ctypes.c_size_t) for n in ("arena", "ordblks", "smblks", "hblks", "hblkhd", "usmblks", "fsmblks",
                                               "uordblks", "fordblks", "keepcost")]
libc = ctypes.CDLL("libc.so.6")
libc.mallinfo2.restype, libc.malloc.restype = Info, ctypes.c_void_p
libc.malloc.argtypes, libc.free.argtypes = [ctypes.c_size_t], [ctypes.c_void_p]
tuned = tune_malloc()
before = libc.mallinfo2().hblkhd
block = libc.malloc(8 << 20)
ctypes.memset(block, 1, 8 << 20)
mapped = libc.mallinfo2().hblkhd - before
libc.free(block)
print(json.dumps({"tuned": tuned, "again": tune_malloc(), "mapped": mapped, "free_in_heap": libc.mallinfo2().fordblks}))
"""


def _probe(**env) -> dict:
    full = {k: v for k, v in os.environ.items() if not k.startswith("MALLOC_") and k != "MORL_TRL_MALLOC"}
    full.update(env)
    out = subprocess.run([sys.executable, "-c", PROBE, str(ROOT / "morl_trl" / "training" / "allocator.py")], env=full, capture_output=True, text=True, timeout=600)  # (a hang guard)
    assert out.returncode == 0, out.stderr
    return json.loads(out.stdout.strip().splitlines()[-1])


def test_a_freed_large_block_stays_in_the_heap():
    got = _probe()
    assert got["tuned"] is True and got["again"] is True
    assert got["mapped"] == 0  # served from the heap, not mmap
    assert got["free_in_heap"] >= 8 << 20  # and kept there once freed (not trimmed)


@pytest.mark.parametrize("env", [{"MORL_TRL_MALLOC": "0"}, {"MORL_TRL_MALLOC": "off"},
                                 {"MALLOC_TRIM_THRESHOLD_": "131072"}])
def test_turned_off_or_left_to_the_users_settings(env):
    got = _probe(**env)
    assert got["tuned"] is False
    if "MORL_TRL_MALLOC" in env:  # glibc's defaults: a block of 8 MiB is mapped on its own
        assert got["mapped"] >= 8 << 20


class _Tuned(Exception):
    pass


# the own recipes (Envelope, GPI, the actor-critics', PCN's, PGMORL's, MORL/D's); every recipe module's tune_malloc
# is stubbed, and build_agent's (algorithms/registry.py: the Agent loop's)
@pytest.mark.parametrize("algo", ["envelope", "gpi_ls", "sac", "pcn", "pgmorl", "morld"])
def test_every_training_path_sets_the_allocator_before_building_the_agent(algo, tmp_path, monkeypatch):
    import importlib

    from morl_trl.recipes import resolve_config, train

    def tuned():
        raise _Tuned

    for name in ("morl_trl.algorithms.envelope.recipe", "morl_trl.algorithms.gpi.recipe", "morl_trl.algorithms.actor_critic.recipe",
                 "morl_trl.algorithms.pcn.recipe", "morl_trl.algorithms.pgmorl.recipe", "morl_trl.algorithms.morld.recipe",
                 "morl_trl.algorithms.registry"):
        monkeypatch.setattr(importlib.import_module(name), "tune_malloc", tuned, raising=False)
    env_id, layout = "MOLavaGridDR-v0", {}
    if algo == "pgmorl":  # (continuous actions; 1 member on the 2 sub-envs)
        pytest.importorskip("mujoco", reason="PGMORL runs on MuJoCo: needs mujoco")
        env_id, layout = "MOHopperDR-v5", dict(pgmorl_pop=1, pgmorl_envs_per_member=2, frames_per_batch=64)
    with pytest.raises(_Tuned):
        train(resolve_config(algo, env_id, run_dir=str(tmp_path / algo), frames=64, num_envs=2, progress=False,
                             **layout))
    assert not (tmp_path / algo).exists()  # (raised while building: nothing written)
