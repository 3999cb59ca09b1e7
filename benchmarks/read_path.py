"""What a reader reads from ``morl-trl train ALGO`` to the loss: files, lines and calls (issue 46).

Runs ``morl-trl train ALGO ENV_ID --quick`` in this process under a trace function through its first
``update`` and records the package's Python frames on the stack when the recipe's ``update`` is
entered and every package function the loop's per-batch step calls through that update. It prints

* **calls from ``main`` to ``update``**: the call edges between ``morl_trl.cli.main`` and the
  recipe's ``update`` on the real stack (a lambda or helper in between counts);
* **files and lines read**: every package file holding a frame of that stack, or a function the
  loop's first ``on_batch`` calls (its store, the updates due, its first update whole). The algorithm's own files -- its ``recipe.py`` and its loss's module --
  count whole (a reader reads them top to bottom); every other file counts only the functions on
  the stacks (a reader follows the call, not the rest of ``cli.py``).

What the loop and the loss use as components (:data:`COMPONENTS`: the env and its transforms, the
replay buffer, the evaluator, the run directory, the configuration, the networks, value estimators and
target updaters) is not counted, as TorchRL's replay buffer, collector, networks and value estimators
are not counted when one reads its ``sota-implementations/sac``.

    python benchmarks/read_path.py                     # envelope and capql
    python benchmarks/read_path.py --algos envelope --env deep-sea-treasure-v0
"""

from __future__ import annotations

import argparse
import ast
import contextlib
import io
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PACKAGE = ROOT / "morl_trl"

#: algorithm -> (training env id, overrides for a run that reaches its first update in a few frames)
CASES = {
    "envelope": ("MOLavaGridDR-v0", ["init_random_frames=64", "frames_per_batch=64", "num_envs=2"]),
    "capql": ("MOHopperDR-v5", ["init_random_frames=64", "frames_per_batch=64", "num_envs=2"]),
}


def _function_spans(path: Path) -> dict[int, tuple[int, int]]:
    """``line of a def or of its first decorator -> (first, last line)`` of every function in ``path``."""
    spans = {}
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.Lambda)):
            first = min([node.lineno, *(d.lineno for d in getattr(node, "decorator_list", []))])
            spans[node.lineno] = spans[first] = (first, node.end_lineno)  # (co_firstlineno: the decorator's)
    return spans


class _Stop(BaseException):
    """Ends the traced run at the second ``update`` (the first one has been read whole)."""


#: what the loop and the loss use as components, as TorchRL's are used (not counted): the env and its
#: transforms, the replay buffer, the run directory, the evaluator, preferences, the configuration, the
#: losses' base class (input checks and keys: TorchRL's ``LossModule`` in ``objectives/common.py``), the
#: networks, value estimators and target updaters, the TorchRL-version shims and log filters
COMPONENTS = ("data/", "envs/", "transforms/", "runs/", "evaluation/", "preferences/", "recipes/config/",
              "objectives/common.py", "objectives/networks.py", "objectives/value.py", "objectives/updaters.py",
              "objectives/fast_path.py", "_torchrl_compat.py", "_quiet.py")


class _Recorder:
    """A trace function (calls only): the package's stack at the first ``update``, and every package
    function outside the components that the loop's first ``on_batch`` calls up to its second ``update``
    (the store, the updates due, the whole first update)."""

    def __init__(self):
        self.chain: list | None = None
        self.loss = None
        self.called: set = set()
        self.recording = False

    def __call__(self, frame, event, arg):
        code = frame.f_code
        path = Path(code.co_filename)
        if event != "call" or not path.is_relative_to(PACKAGE):
            return None
        rel = path.relative_to(PACKAGE).as_posix()
        if code.co_name == "on_batch" and rel.startswith("algorithms/"):
            self.recording = True
        if code.co_name == "update" and rel.startswith("algorithms/"):
            self.recording = True
            if self.chain is not None:
                raise _Stop
            self.chain = []
            f = frame
            while f is not None:
                if Path(f.f_code.co_filename).is_relative_to(PACKAGE):
                    self.chain.append((Path(f.f_code.co_filename), f.f_code.co_firstlineno, f.f_code.co_qualname))
                f = f.f_back
            self.chain.reverse()
            self.loss = frame.f_locals["agent"].loss
        elif self.recording and not rel.startswith(COMPONENTS):
            self.called.add((path, code.co_firstlineno, code.co_qualname))
        return None


def read_path(algo: str, env_id: str, overrides: list[str]) -> dict:
    """Run the CLI under the recorder until the first optimizer step; returns ``{"calls", "chain", "files": {path: lines}, "lines"}``."""
    from morl_trl.cli import main

    recorder = _Recorder()
    with tempfile.TemporaryDirectory() as tmp:
        argv = ["train", algo, env_id, "--quick", "--frames", "128", "--run-dir", f"{tmp}/run", "--no-progress",
                "--logger", "none", *overrides, "eval_weights=3"]
        sys.settrace(recorder)
        try:
            with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
                main(argv)
        except _Stop:
            pass
        finally:
            sys.settrace(None)
    if recorder.chain is None:
        raise RuntimeError(f"{algo}: the run never reached an update")
    chain = [name for _, _, name in recorder.chain]
    start = next(i for i, name in enumerate(chain) if name == "main")
    calls = len(chain) - 1 - start
    recipe = recorder.chain[-1][0]
    whole = {recipe, Path(sys.modules[type(recorder.loss).__module__].__file__)}
    functions = set(recorder.chain[start:]) | recorder.called
    files: dict[Path, int] = {path: len(path.read_text().splitlines()) for path in whole}
    spans: dict[Path, set[tuple[int, int]]] = {}
    for path, first, _ in functions:
        if path in whole:
            continue
        span = _function_spans(path).get(first)
        if span is not None:
            spans.setdefault(path, set()).add(span)
    names = {}
    for path, first, name in functions:
        if path not in whole and "<" not in name:
            names.setdefault(path, set()).add(name)
    for path, ranges in spans.items():  # (nested functions inside a counted one count once)
        lines: set[int] = set()
        for first, last in ranges:
            lines.update(range(first, last + 1))
        files[path] = len(lines)
    return {"calls": calls, "chain": chain[start:], "files": files, "lines": sum(files.values()),
            "whole": whole, "functions": {path: sorted(n) for path, n in names.items()}}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--algos", default=",".join(CASES), help=f"comma-separated, of {list(CASES)}")
    parser.add_argument("--env", help="training env id (default: the case's)")
    parser.add_argument("--functions", action="store_true", help="name the functions counted in each file")
    args = parser.parse_args(argv)
    for algo in args.algos.split(","):
        env_id, overrides = CASES[algo]
        result = read_path(algo, args.env or env_id, overrides)
        print(f"{algo}: {len(result['files'])} files, {result['lines']} lines, {result['calls']} calls from main "
              f"to update ({' -> '.join(result['chain'])})")
        for path, lines in sorted(result["files"].items(), key=lambda item: -item[1]):
            how = "whole file" if path in result["whole"] else "functions on the path"
            print(f"  {path.relative_to(ROOT).as_posix():48s} {lines:5d}  ({how})")
            if args.functions and path not in result["whole"]:
                print(f"      {', '.join(result['functions'].get(path, []))}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
