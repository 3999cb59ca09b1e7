"""Where one update's time goes: each tensor operation of ours, timed at the dispatcher.

Builds ours as ``bench_losses.py`` does (the paper's settings), runs ``--updates`` plain updates
(process CPU time, one torch thread), then as many again with every aten operation timed
(``TorchDispatchMode``; the timing itself adds ~10 us per operation, so the per-operation sum
exceeds the plain figure by about that times the operation count). Prints the plain ms per
update, the operations per update, the share of the matrix products (``mm``, ``addmm``,
``bmm``, ``baddbmm``) in the plain update, and the costliest operations:

    python benchmarks/profile_update.py gpi_ls
    python benchmarks/profile_update.py capql --updates 20 --top 15
"""

from __future__ import annotations

import argparse
import collections
import sys
import time
from pathlib import Path

import torch
from torch.utils._python_dispatch import TorchDispatchMode

sys.path.insert(0, str(Path(__file__).resolve().parent))
import bench_losses as bench  # noqa: E402

MATMULS = ("aten.mm.", "aten.addmm.", "aten.bmm.", "aten.baddbmm.")


def build(method: str, filled: int = 100_000):
    """Ours for ``method`` (``capql``, ``gpi_ls``, ``gpi_pd``, ``pcn``, ``morld``, ``envelope``), as bench_losses builds it."""
    if method == "envelope":
        c = bench.ENVELOPE
        return bench.ours_envelope(bench.random_transitions(filled, c["obs"], c["k"], num_actions=c["actions"]), filled)[0]
    if method == "capql":
        c = bench.CAPQL
        return bench.ours_capql(bench.random_transitions(filled, c["obs"], c["k"], act_dim=c["act"], seed=1), filled)
    if method in ("gpi_ls", "gpi_pd"):
        g = bench.GPI
        tr = bench.random_transitions(filled, g["obs"], g["k"], num_actions=g["actions"])
        return bench.ours_gpi(tr, bench.gpi_support(), filled, method == "gpi_pd")
    if method == "pcn":
        e = bench.ENVELOPE
        return bench.ours_pcn(bench.pcn_episodes(1000, e["obs"], e["actions"], e["k"]))
    if method == "morld":
        c = bench.CAPQL
        return bench.ours_morld(bench.morld_transitions(filled, c["obs"], c["act"], c["k"]), filled)[0]
    raise SystemExit(f"unknown method {method!r}; valid: envelope, capql, gpi_ls, gpi_pd, pcn, morld")


class _OpTimer(TorchDispatchMode):
    def __init__(self):
        super().__init__()
        self.seconds, self.calls = collections.Counter(), collections.Counter()

    def __torch_dispatch__(self, func, types, args=(), kwargs=None):
        t = time.process_time()
        out = func(*args, **(kwargs or {}))
        self.seconds[str(func)] += time.process_time() - t
        self.calls[str(func)] += 1
        return out


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("method")
    p.add_argument("--updates", type=int, default=20)
    p.add_argument("--top", type=int, default=12)
    p.add_argument("--filled", type=int, default=100_000, help="replay transitions (the benchmark's 100,000)")
    args = p.parse_args(argv)
    torch.set_num_threads(1)
    from morl_trl.training.allocator import tune_malloc

    tune_malloc()
    step = build(args.method, args.filled)
    for _ in range(5):
        step()
    n = args.updates
    t = time.process_time()
    for _ in range(n):
        step()
    plain = (time.process_time() - t) / n * 1e3
    with _OpTimer() as timer:
        for _ in range(n):
            step()
    matmul = sum(v for k, v in timer.seconds.items() if k.startswith(MATMULS)) / n * 1e3
    print(f"{args.method}: {plain:.2f} ms per update (process CPU time, 1 thread); "
          f"{sum(timer.calls.values()) / n:.0f} tensor operations per update; "
          f"matrix products {matmul:.2f} ms = {matmul / plain:.0%} of the update")
    for k, v in timer.seconds.most_common(args.top):
        print(f"  {v / n * 1e3:8.3f} ms  {timer.calls[k] / n:6.1f} x  {k}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
