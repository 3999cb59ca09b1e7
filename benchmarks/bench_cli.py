"""How fast the command line answers when it has nothing to run: ``--help`` and argument errors.

Each case is a fresh ``python -m morl_trl.cli ...`` process (what a user waits for), timed
beside ``python -c "import torch"`` in the same run (the floor a command that imports torch
cannot go under), ``--repeat`` times each, interleaved; the best time of each is printed with
its ratio to ``import torch``. The goal (issue 45): under 1 s each, well under ``import torch``.

    python benchmarks/bench_cli.py [--repeat 5]
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

#: name -> the arguments of ``morl-trl`` (the import of torch is timed as ``import torch``)
CASES = {
    "morl-trl --help": ["--help"],
    "morl-trl train --help": ["train", "--help"],
    "morl-trl train (no arguments: error)": ["train"],
    "morl-trl train envelop ... (unknown algorithm)": ["train", "envelop", "deep-sea-treasure-v0"],
    "morl-trl train ... --frames 0 (bad value)": ["train", "envelope", "deep-sea-treasure-v0", "--frames", "0"],
    "morl-trl train ... learning_rate=1e-3 (unknown key)": ["train", "envelope", "deep-sea-treasure-v0",
                                                             "learning_rate=1e-3"],
}


def _time(cmd: list[str]) -> float:
    env = {**os.environ, "PYTHONPATH": str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", "")}
    start = time.perf_counter()
    subprocess.run(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, env=env, cwd=ROOT, check=False)
    return time.perf_counter() - start


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--repeat", type=int, default=5, help="runs of each command (the best is kept)")
    args = p.parse_args(argv)
    commands = {"python -c 'import torch'": [sys.executable, "-c", "import torch"]}
    commands.update({name: [sys.executable, "-m", "morl_trl.cli", *a] for name, a in CASES.items()})
    best = {name: float("inf") for name in commands}
    for _ in range(args.repeat):  # interleaved: a busy moment of the machine falls on every command alike
        for name, cmd in commands.items():
            best[name] = min(best[name], _time(cmd))
    torch_s = best.pop("python -c 'import torch'")
    print(f"{'command':58s} {'best of ' + str(args.repeat):>10s} {'/ import torch':>15s}")
    print(f"{'python -c import torch':58s} {torch_s:9.2f}s {1.0:14.2f}x")
    for name, seconds in best.items():
        print(f"{name:58s} {seconds:9.2f}s {seconds / torch_s:14.2f}x")
    slow = [n for n, s in best.items() if s >= 1.0]
    print("every command under 1 s" if not slow else f"{len(slow)} command(s) at 1 s or more: {slow}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
