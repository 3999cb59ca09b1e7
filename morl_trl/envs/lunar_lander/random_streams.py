"""Per-sub-env random generators whose per-step draws are fetched in blocks.

Each LunarLander step draws two ``uniform(-1, 1)`` numbers (the engine dispersion) from its
sub-env's generator, whether or not an engine fires. One generator call per sub-env per step
would cost more than the rest of the non-Box2D work, so :class:`BlockUniformStreams` draws a
block of steps at once and serves rows from it. A reset needs the generator exactly where
Gymnasium's would be, so :meth:`BlockUniformStreams.generator` rewinds to the start of the
current block and re-draws only what was consumed: the stream of numbers is unchanged.
"""

from __future__ import annotations

import numpy as np

__all__ = ["BlockUniformStreams"]


class BlockUniformStreams:
    """``num`` generators, each yielding rows of ``width`` ``uniform(-1, 1) / divisor`` draws.

    Sub-env ``i`` is seeded like Gymnasium's ``reset(seed=seed + i)``
    (``np.random.Generator(PCG64(SeedSequence(seed + i)))``).

    Example:
        >>> s = BlockUniformStreams(2, seed=0)
        >>> rows = s.take(np.array([0, 1]))           # one row per sub-env
        >>> g = np.random.default_rng(0)
        >>> bool((rows[0] == g.uniform(-1.0, 1.0, size=2)).all())
        True
        >>> s.generator(0).uniform() == g.uniform()    # rewound to exactly after row 0
        True
    """

    def __init__(self, num: int, seed: int, width: int = 2, block: int = 64, divisor: float = 1.0) -> None:
        self.num, self.width, self.block, self.divisor = num, width, block, divisor
        self.buffer = np.empty((num, block, width))
        self._all = np.arange(num)
        self.seed(seed)

    def seed(self, seed: int) -> None:
        """Re-seed every generator and drop the prefetched rows."""
        self.rngs = [np.random.default_rng(seed + i) for i in range(self.num)]
        self.pos = np.full(self.num, self.block, dtype=np.int64)
        self.block_start = [None] * self.num
        self.headroom = 0  # rows every sub-env has left in its block: take() without checks

    def generator(self, i: int) -> np.random.Generator:
        """Sub-env ``i``'s generator, positioned right after the rows already taken."""
        used = int(self.pos[i])
        if used < self.block:
            rng = self.rngs[i]
            # restoring the whole state dict also restores PCG64's buffered uint32 half,
            # which ``integers`` uses; ``advance`` would clear it
            rng.bit_generator.state = self.block_start[i]
            rng.random(used * self.width)
            self.pos[i] = self.block
            self.block_start[i] = None
            self.headroom = 0
        return self.rngs[i]

    def take(self, idx: np.ndarray | None = None) -> np.ndarray:
        """The next row ``[len(idx), width]`` of each sub-env in ``idx`` (all if ``None``)."""
        if idx is None:
            if self.headroom > 0:  # the common case: one gather
                self.headroom -= 1
                pos = self.pos
                rows = self.buffer[self._all, pos]
                pos += 1
                return rows
            idx = self._all
        pos = self.pos[idx]
        empty = pos >= self.block
        if empty.any():
            for i in idx[empty].tolist():
                rng = self.rngs[i]
                self.block_start[i] = rng.bit_generator.state
                self.buffer[i] = rng.uniform(-1.0, 1.0, size=(self.block, self.width)) / self.divisor
            self.pos[idx[empty]] = 0
            pos = self.pos[idx]
        self.pos[idx] = pos + 1
        self.headroom = self.block - int(self.pos.max())
        return self.buffer[idx, pos]
