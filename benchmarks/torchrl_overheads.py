"""TorchRL's own per-call costs on a one-env run (issue 47): tiny reproducers for an upstream note.

Each row times one TorchRL call on a one-transition batch (process CPU time, one thread) beside
what it has to do, on the transition layout of Envelope on deep-sea-treasure:

1. ``TensorDictReplayBuffer.extend`` of one transition, and (the default transform, an empty
   ``Compose``) the clone its ``inv`` makes first (on a one-transition batch as cheap as the
   shallow copy that would replace it: :class:`~morl_trl.data.lean.LeanTensorDictReplayBuffer`
   keeps TorchRL's ``extend``);
2. ``TensorDictReplayBuffer.sample`` against the sampler call + ``storage.get`` it wraps, and
   :class:`~morl_trl.data.lean.LeanTensorDictReplayBuffer`'s;
3. a collector batch's ``clone()`` (``Collector.iterator`` clones every batch unless
   ``return_same_td=True``), which with ``frames_per_batch=1`` is a copy per frame;
4. ``TensorDict.set`` of an entry a one-env step writes (a ``[1, 2]`` float) against the same write
   without the value validation (``_set_str(..., validated=True)``) and a ``dict`` store: an env step
   and its transforms write about nine such entries;
5. TorchRL's ``EGreedyModule`` on a one-env batch against the tensor ops it performs (a uniform draw
   against ε, ``spec.rand()``, ``torch.where``, one write);
6. a ``TensorDictModule`` around a ``[64, 64]`` MLP against the MLP's own call on the same tensors.

    python benchmarks/torchrl_overheads.py
"""

from __future__ import annotations

import time

import torch
from tensordict import TensorDict
from torchrl.data import LazyTensorStorage, RandomSampler, TensorDictReplayBuffer


CALLS = 3000  # per row (--calls)


def _timed(fn, n: int | None = None) -> float:
    n = CALLS if n is None else n
    for _ in range(min(100, n)):
        fn()
    t = time.process_time()
    for _ in range(n):
        fn()
    return (time.process_time() - t) / n * 1e6


def _transition() -> TensorDict:
    return TensorDict({"observation": torch.randn(1, 2), "action": torch.randint(4, (1,)),
                       "next": TensorDict({"observation": torch.randn(1, 2), "reward": torch.randn(1, 2),
                                           "done": torch.zeros(1, 1, dtype=torch.bool),
                                           "terminated": torch.zeros(1, 1, dtype=torch.bool)}, [1])}, [1],
                      device="cpu")


def main(argv: list[str] | None = None) -> int:
    import argparse

    global CALLS
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--calls", type=int, default=CALLS, help="timed calls per row")
    CALLS = p.parse_args(argv).calls
    torch.set_num_threads(1)
    from morl_trl.data.lean import LeanTensorDictReplayBuffer

    x = _transition()
    rows = []
    for cls in (TensorDictReplayBuffer, LeanTensorDictReplayBuffer):
        rb = cls(storage=LazyTensorStorage(100_000), sampler=RandomSampler(), batch_size=32)
        rows.append((f"{cls.__name__}.extend (1 transition)", _timed(lambda: rb.extend(x))))
        rows.append((f"{cls.__name__}.sample (32)", _timed(rb.sample)))
    rb = TensorDictReplayBuffer(storage=LazyTensorStorage(100_000), batch_size=32)
    rb.extend(x)
    rows.append(("  of which: empty Compose.inv (a clone)", _timed(lambda: rb._transform.inv(x))))
    rows.append(("  sampler.sample + storage.get", _timed(lambda: rb.storage.get(rb._sampler.sample(rb.storage, 32)[0]))))
    batch = TensorDict({**{f"k{i}": torch.zeros(1, 1, 2) for i in range(12)},
                        "next": TensorDict({f"k{i}": torch.zeros(1, 1, 2) for i in range(10)}, [1, 1])}, [1, 1])
    rows.append(("collector batch clone (22 entries, [1, 1])", _timed(batch.clone)))
    rows += _per_step_rows()
    print(f"torch {torch.__version__}; us per call (process CPU time, 1 thread)")
    for name, us in rows:
        print(f"  {name:<48} {us:8.1f}")
    return 0


def _per_step_rows() -> list[tuple[str, float]]:
    """Rows 4-6: the per-call costs inside a one-env step (the env's writes, ε-greedy, a module call)."""
    from tensordict.nn import TensorDictModule
    from torchrl.data import Categorical
    from torchrl.envs.utils import ExplorationType, set_exploration_type
    from torchrl.modules import MLP, EGreedyModule

    rows = []
    td = TensorDict({"observation": torch.zeros(1, 2), "reward": torch.zeros(1, 2)}, [1])
    value, plain = torch.ones(1, 2), {}
    rows.append(("TensorDict.set ([1, 2] float, existing key)", _timed(lambda: td.set("reward", value))))
    rows.append(("  the same write, validated=True", _timed(
        lambda: td._set_str("reward", value, validated=True, inplace=False))))
    rows.append(("  a dict store", _timed(lambda: plain.__setitem__("reward", value))))

    spec = Categorical(4, shape=(1,))
    egreedy = EGreedyModule(spec, eps_init=0.5)
    td.set("action", torch.zeros(1, dtype=torch.long))
    eps = egreedy.eps

    def by_hand():  # what EGreedyModule.forward computes for this batch
        cond = torch.rand(td.shape) < eps
        td.set("action", torch.where(cond, spec.rand(), td.get("action")))

    with set_exploration_type(ExplorationType.RANDOM):
        rows.append(("EGreedyModule (one-env batch)", _timed(lambda: egreedy(td))))
        rows.append(("  its tensor ops and one write", _timed(by_hand)))

    mlp = MLP(in_features=4, out_features=8, num_cells=[64, 64])
    module = TensorDictModule(lambda o, w: mlp(torch.cat([o, w], -1)), in_keys=["observation", "reward"],
                              out_keys=["action_value"])
    o, w = td.get("observation"), td.get("reward")
    rows.append(("TensorDictModule([64, 64] MLP) call", _timed(lambda: module(td))))
    rows.append(("  the MLP's own call", _timed(lambda: mlp(torch.cat([o, w], -1)))))
    return rows


if __name__ == "__main__":
    raise SystemExit(main())
