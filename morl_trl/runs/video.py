"""A TorchRL logger that writes the clips of ``VideoRecorder`` on any install.

TorchRL's :class:`~torchrl.record.loggers.CSVLogger` writes ``video_format="mp4"`` through
``torchcodec``; where it is not installed, :class:`VideoCSVLogger` writes animated GIFs with
``imageio`` (Pillow's GIF writer: no ffmpeg needed). ``video_format="auto"`` picks mp4 when it
can be written, else gif.
"""

from __future__ import annotations

import importlib.util
import os

import torch
from torchrl.record.loggers import CSVLogger

__all__ = ["VideoCSVLogger", "mp4_available"]


def mp4_available() -> bool:
    """Whether TorchRL's CSVLogger can write mp4 here (it needs ``torchcodec``)."""
    return importlib.util.find_spec("torchcodec") is not None


class VideoCSVLogger(CSVLogger):
    """:class:`~torchrl.record.loggers.CSVLogger` with ``video_format="gif"`` (and ``"auto"``).

    Clips land in ``<log_dir>/<exp_name>/videos/<tag>_<step>.<gif|mp4|pt>``. A GIF holds the
    whole episode: past ``max_gif_frames`` frames it keeps every ``ceil(T / max_gif_frames)``-th
    one and shows each that much longer, so a 1000-step episode plays in the same time as
    unsubsampled, at a fraction of the size (``max_gif_frames=None`` keeps every frame).
    """

    def __init__(self, exp_name: str, log_dir: str, *, video_format: str = "auto", video_fps: int = 30,
                 max_gif_frames: int | None = 250) -> None:
        if max_gif_frames is not None and (isinstance(max_gif_frames, bool) or int(max_gif_frames) < 2):
            raise ValueError(f"max_gif_frames must be an int >= 2 or None, got {max_gif_frames!r}")
        self.max_gif_frames = max_gif_frames
        if video_format == "auto":
            video_format = "mp4" if mp4_available() else "gif"
        if video_format not in ("gif", "mp4", "pt", "memmap"):
            raise ValueError(f"video_format must be 'auto', 'gif', 'mp4', 'pt' or 'memmap', got {video_format!r}")
        super().__init__(exp_name, log_dir=log_dir, video_format="pt" if video_format == "gif" else video_format,
                         video_fps=video_fps)
        self.video_format = video_format
        self.written: list[str] = []

    def log_video(self, name: str, video: torch.Tensor, step: int | None = None, **kwargs) -> None:
        if self.video_format != "gif":
            super().log_video(name, video, step=step, **kwargs)
            ext = {"mp4": ".mp4", "pt": ".pt", "memmap": ".memmap"}[self.video_format]
            self.written.append(os.path.join(self.experiment.log_dir, "videos", f"{name}_{step}{ext}"))
            return
        import imageio.v2 as imageio

        if video.dim() != 5 or video.size(2) not in (1, 3):
            raise ValueError(f"a video is [N, T, C, H, W] with C in (1, 3), got shape {tuple(video.shape)}")
        frames = video.flatten(0, 1).permute(0, 2, 3, 1)  # [T, H, W, C]
        frames = frames.expand(*frames.shape[:-1], 3).to(torch.uint8).cpu().numpy()
        fps = kwargs.get("fps", self.video_fps)
        stride = 1
        if self.max_gif_frames is not None and len(frames) > self.max_gif_frames:
            stride = -(-len(frames) // self.max_gif_frames)
            keep = list(range(0, len(frames), stride))
            if keep[-1] != len(frames) - 1:
                keep.append(len(frames) - 1)  # the episode's last frame (how it ended) is always shown
            frames = frames[keep]
        path = os.path.join(self.experiment.log_dir, "videos", f"{name}_{step}.gif")
        os.makedirs(os.path.dirname(path), exist_ok=True)
        imageio.mimsave(path, list(frames), duration=1000.0 * stride / fps, loop=0)
        self.written.append(path)
