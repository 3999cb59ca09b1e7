"""How long the rest of a run takes: :class:`DurationEstimate`, what the progress bar and
``log.txt`` say.

A run's time is three kinds of work, measured apart:

* learning: frames after the random warm-up, at the rate of the last minute of learning (the
  warm-up, which makes no updates, runs several times faster and is not counted in it; the rate
  of a machine shared with other work changes, so the recent rate is used, not the first one);
* evaluations: those still due (every ``eval_interval`` frames and the last one), each as long
  as the last evaluation of a trained policy (the untrained policy's, at frame 0, ends its
  episodes sooner: it is used only until there is another);
* the end: the random policy's evaluation, the floors at the run's weights (a few trivial
  policies' evaluations) and the report's plots, as long as :data:`END_EVALUATIONS`
  evaluations (all of it slows down with the machine as evaluations do) and
  :data:`END_SECONDS` (the final checkpoint).

The first estimate comes once 15 s of learning are measured (``log.txt``); it is then renewed
after every evaluation (``log.txt``) and at every batch (the progress bar).

Example:
    >>> from types import SimpleNamespace
    >>> cfg = SimpleNamespace(frames=60_000, init_random_frames=2_000, eval_interval=10_000)
    >>> clock = [0.0]
    >>> eta = DurationEstimate(cfg, 0, clock=lambda: clock[0])
    >>> eta.evaluated(0, 1.0)                       # frame 0: the untrained policy, 1 s
    >>> for frames in range(2_048, 12_288, 1_024):  # learning: 1,024 frames every 2 s
    ...     clock[0] += 2.0
    ...     eta.batch(frames)
    >>> eta.evaluated(11_264, 3.0); clock[0] += 3.0  # a trained policy's evaluation: 3 s
    >>> eta.rate()                                  # 9,216 frames in 18 s of learning
    (512.0, 9216)
    >>> round(eta.seconds_left(11_264, 20_000), 1)  # 48,736 frames at 512/s + 5 evaluations of 3 s + the end
    135.2
"""

from __future__ import annotations

import time
from typing import Callable

__all__ = ["DurationEstimate", "END_EVALUATIONS", "END_SECONDS", "hms"]

#: the end of a run besides its last evaluation, in evaluations' time and seconds: measured on the
#: main job (2-core CPU at load ~8, 2026-12-01) as ~25 s after evaluations of ~3 s
END_EVALUATIONS, END_SECONDS = 7.0, 4.0

#: seconds of learning measured before the first estimate, and the window of the learning rate
FIRST_AFTER, WINDOW = 15.0, 60.0


def hms(seconds: float) -> str:
    """``"2 h 01 min"``, ``"3 min 09 s"``, ``"42 s"``.

    Example:
        >>> hms(2 * 3600 + 61), hms(189), hms(41.6)
        ('2 h 01 min', '3 min 09 s', '42 s')
    """
    seconds = int(round(seconds))
    h, rem = divmod(seconds, 3600)
    m, s = divmod(rem, 60)
    return f"{h} h {m:02d} min" if h else (f"{m} min {s:02d} s" if m else f"{s} s")


def _plural(n: int, word: str) -> str:
    return f"{n} {word}" if n == 1 else f"{n} {word}s"


class DurationEstimate:
    """The time left of a run (see the module docstring).

    Args:
        cfg: the run's config (``frames``, ``init_random_frames``, ``eval_interval``).
        frames: the frames already done (a resumed run's).
        clock: seconds, monotonic (``time.perf_counter``).
    """

    def __init__(self, cfg, frames: int, *, clock: Callable[[], float] = time.perf_counter) -> None:
        self.total = int(cfg.frames)
        self.warmup = int(getattr(cfg, "init_random_frames", 0) or 0)
        self.interval = max(int(cfg.eval_interval), 1)
        self.clock = clock
        self.eval_total = 0.0  # seconds spent evaluating (left out of the learning rate)
        self.eval_seconds: float | None = None  # the last evaluation's (a trained policy's once there is one)
        self.trained_eval = False
        self.samples: list[tuple[int, float]] = []  # (frames, learning seconds) of the learning batches
        self.said = frames >= self.total

    def _learning_clock(self) -> float:
        return self.clock() - self.eval_total

    def batch(self, frames: int) -> None:
        """After a batch: the run has ``frames`` frames."""
        if frames > self.warmup:
            self.samples.append((frames, self._learning_clock()))

    def evaluated(self, frames: int, seconds: float) -> None:
        """An evaluation at ``frames`` took ``seconds``."""
        self.eval_total += seconds
        if frames > 0 or not self.trained_eval:
            self.eval_seconds = seconds
            self.trained_eval = self.trained_eval or frames > 0

    def rate(self) -> tuple[float, int] | None:
        """``(frames per second of learning, frames it is measured over)`` over the last
        :data:`WINDOW` seconds of learning; ``None`` before :data:`FIRST_AFTER` seconds of it."""
        if len(self.samples) < 2 or self.samples[-1][1] - self.samples[0][1] < FIRST_AFTER:
            return None
        end_f, end_t = self.samples[-1]
        start = next((s for s in self.samples if end_t - s[1] <= WINDOW), self.samples[0])
        if start[1] >= end_t:
            start = self.samples[0]
        return (end_f - start[0]) / max(end_t - start[1], 1e-9), end_f - start[0]

    def evaluations_left(self, frames: int, next_eval: int) -> int:
        """The evaluations still due: every ``eval_interval`` frames from ``next_eval`` and the last."""
        if frames >= self.total:
            return 0
        return max(self.total - next_eval, 0) // self.interval + 1

    def seconds_left(self, frames: int, next_eval: int) -> float | None:
        """Seconds until the run ends, ``None`` until the learning rate is measured."""
        measured = self.rate()
        if measured is None:
            return None
        left = max(self.total - frames, 0)
        per_eval = self.eval_seconds or 0.0
        return left / max(measured[0], 1e-9) + self.evaluations_left(frames, next_eval) * per_eval + self.end_seconds()

    def end_seconds(self) -> float:
        """The end of the run after its last evaluation (see the module docstring)."""
        return END_EVALUATIONS * (self.eval_seconds or 0.0) + END_SECONDS

    def line(self, frames: int, next_eval: int) -> str | None:
        """``"estimated duration: ... more (...)"``: how it is made, for ``log.txt``; ``None``
        until the learning rate is measured."""
        seconds = self.seconds_left(frames, next_eval)
        if seconds is None:
            return None
        rate, over = self.rate()
        evals = self.evaluations_left(frames, next_eval)
        per_eval = self.eval_seconds or 0.0
        which = "" if self.trained_eval else ", an untrained policy's"
        return (f"estimated duration: {hms(seconds)} more ({max(self.total - frames, 0):,} frames at {rate:,.0f} "
                f"frames/s learning, measured over the last {over:,} frames, + {_plural(evals, 'evaluation')} of "
                f"~{per_eval:.0f} s{which}, + ~{self.end_seconds():.0f} s for the end)")

    def first_line(self, frames: int, next_eval: int) -> str | None:
        """:meth:`line` once, as soon as the learning rate is measured (then ``None``)."""
        if self.said:
            return None
        text = self.line(frames, next_eval)
        if text is not None:
            self.said = True
        return text
