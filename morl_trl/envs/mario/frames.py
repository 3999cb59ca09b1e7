"""The Atari-style frame pipeline of MO-SuperMarioBros, batched in torch.

SPEC §1.4 applies, per agent step: max over the last two raw RGB frames of the 4-frame skip,
``Resize(84, 84)`` (OpenCV ``INTER_AREA``), ``Grayscale`` (Gymnasium's weights
``0.2125 R + 0.7154 G + 0.0721 B``, truncated to ``uint8``) and a stack of the last 4
frames.

Both the resize and the grayscale are linear, so we take the grayscale first (one channel
instead of three) and resize it with :class:`AreaResize`, OpenCV's ``INTER_AREA``
downscaling written as two small matrices (each output pixel averages the source pixels
its footprint covers, partial pixels weighted by the covered fraction): no OpenCV needed.
The reference rounds each resized colour channel to ``uint8`` before the grayscale sum; we
round once at the end, so a pixel can differ from it by one gray level.
"""

from __future__ import annotations

import math

import torch

__all__ = ["AreaResize", "area_weights", "FramePipeline", "GRAY_WEIGHTS"]

GRAY_WEIGHTS = (0.2125, 0.7154, 0.0721)  # R, G, B: gymnasium.wrappers.GrayscaleObservation


def area_weights(src: int, dst: int) -> torch.Tensor:
    """The ``[dst, src]`` matrix of 1-D area interpolation (``dst <= src``).

    Output ``j`` covers the source interval ``[j * s, (j + 1) * s)`` with ``s = src / dst``;
    a source sample gets the covered fraction of its unit cell divided by ``s``, so each row
    sums to 1 (OpenCV's ``INTER_AREA`` when shrinking).
    """
    if not 0 < dst <= src:
        raise ValueError(f"area resize needs 0 < dst <= src, got src={src}, dst={dst}")
    scale = src / dst
    weights = torch.zeros(dst, src, dtype=torch.float64)
    for j in range(dst):
        lo, hi = j * scale, (j + 1) * scale
        for i in range(math.floor(lo), min(math.ceil(hi), src)):
            weights[j, i] = (min(hi, i + 1) - max(lo, i)) / scale
    return weights


class AreaResize:
    """Area-average downscaling of float images ``[..., H, W]`` to ``[..., h, w]``.

    Example:
        >>> import torch
        >>> resize = AreaResize((4, 6), (2, 3))
        >>> resize(torch.arange(24.).reshape(4, 6))
        tensor([[ 3.5000,  5.5000,  7.5000],
                [15.5000, 17.5000, 19.5000]])
    """

    def __init__(self, src_hw: tuple[int, int], dst_hw: tuple[int, int]) -> None:
        self.src_hw, self.dst_hw = tuple(src_hw), tuple(dst_hw)
        self.rows = area_weights(self.src_hw[0], self.dst_hw[0]).float()  # [h, H]
        self.cols = area_weights(self.src_hw[1], self.dst_hw[1]).float().T.contiguous()  # [W, w]

    def __call__(self, img: torch.Tensor) -> torch.Tensor:
        if tuple(img.shape[-2:]) != self.src_hw:
            raise ValueError(f"expected images [..., {self.src_hw[0]}, {self.src_hw[1]}], got {tuple(img.shape)}")
        if self.rows.dtype != img.dtype or self.rows.device != img.device:
            self.rows, self.cols = self.rows.to(img), self.cols.to(img)
        return self.rows @ (img @ self.cols)


class FramePipeline:
    """Raw NES frames -> one ``uint8 [h, w]`` grayscale observation frame per sub-env.

    Args:
        src_hw: raw frame size (240, 256).
        dst_hw: observation size (84, 84).
        rgb_channels: where R, G, B sit in the raw frame's last dimension.

    Example:
        >>> import torch
        >>> pipe = FramePipeline((240, 256), (84, 84), rgb_channels=(0, 1, 2))
        >>> white = torch.full((2, 2, 240, 256, 3), 255, dtype=torch.uint8)
        >>> out = pipe(white)
        >>> out.shape, out.dtype, int(out.min()), int(out.max())
        (torch.Size([2, 84, 84]), torch.uint8, 255, 255)
    """

    def __init__(self, src_hw=(240, 256), dst_hw=(84, 84), rgb_channels=(0, 1, 2)) -> None:
        self.resize = AreaResize(src_hw, dst_hw)
        self.rgb_channels = tuple(rgb_channels)
        self._gray = {}  # number of channels -> weight vector

    def __call__(self, last_two: torch.Tensor) -> torch.Tensor:
        """``uint8 [B, 2, H, W, C]`` (the last two raw frames of the skip) -> ``uint8 [B, h, w]``."""
        if last_two.dim() != 5 or last_two.shape[1] != 2:
            raise ValueError(f"expected frames [B, 2, H, W, C], got {tuple(last_two.shape)}")
        pooled = torch.maximum(last_two[:, 0], last_two[:, 1])  # per-channel max, as the reference
        channels = pooled.shape[-1]
        if channels not in self._gray:
            weights = torch.zeros(channels)
            weights[list(self.rgb_channels)] = torch.tensor(GRAY_WEIGHTS)
            self._gray[channels] = weights
        gray = pooled.float() @ self._gray[channels]  # [B, H, W]
        small = self.resize(gray)
        # float32 sums of exact grays land a hair under an integer; truncating like
        # numpy's astype(uint8) must not turn 255 into 254 for a white frame.
        return (small + 1e-3).clamp_(0, 255).to(torch.uint8)
