"""A check the exactness tests share: two TensorDicts hold the same entries, entry for entry."""

import torch
from tensordict import TensorDict


def assert_same_tensordict(a: TensorDict, b: TensorDict, where: str) -> None:
    """The same keys (at every depth), and each entry of the same dtype, shape and values."""
    keys_a, keys_b = sorted(a.keys(True, True), key=str), sorted(b.keys(True, True), key=str)
    assert keys_a == keys_b, where
    for key in keys_a:
        x, y = a.get(key), b.get(key)
        assert x.dtype == y.dtype and x.shape == y.shape, (where, key)
        assert torch.equal(x, y), (where, key, x, y)
