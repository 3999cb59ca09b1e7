"""GIF clips hold the whole episode, subsampled past a frame budget, in real time."""

import pytest
import torch

imageio = pytest.importorskip("imageio.v2")

from morl_trl.runs.video import VideoCSVLogger  # noqa: E402


def _video(t: int) -> torch.Tensor:
    frames = torch.zeros(1, t, 3, 4, 4, dtype=torch.uint8)
    frames[0, :, 0, 0, 0] = torch.arange(t, dtype=torch.uint8)  # frame i carries i in one pixel
    return frames


def test_a_long_episode_is_subsampled_and_keeps_its_last_frame(tmp_path):
    logger = VideoCSVLogger("v", str(tmp_path), video_format="gif", video_fps=50, max_gif_frames=40)
    logger.log_video("ctx", _video(101), step=0)
    gif = imageio.mimread(logger.written[0])
    # stride ceil(101 / 40) = 3: frames 0, 3, ..., 99 and the last one, 100
    assert [int(f[0, 0, 0]) for f in gif] == list(range(0, 101, 3)) + [100]
    reader = imageio.get_reader(logger.written[0])
    assert reader.get_meta_data(0)["duration"] == pytest.approx(60.0)  # 3 frames of 20 ms: real time


def test_a_short_episode_keeps_every_frame(tmp_path):
    logger = VideoCSVLogger("v", str(tmp_path), video_format="gif", video_fps=30)
    logger.log_video("ctx", _video(78), step=5)
    assert len(imageio.mimread(logger.written[0])) == 78 and logger.written[0].endswith("ctx_5.gif")
    with pytest.raises(ValueError, match="max_gif_frames must be an int >= 2 or None, got 1"):
        VideoCSVLogger("v", str(tmp_path), video_format="gif", max_gif_frames=1)
