"""What a run writes: TorchRL logger scalars, tidy CSVs, fronts, a report with plots.

Layout of a run directory::

    config.json                  resolved configuration
    log.txt                      notes: the start, every evaluation (its frame, duration and mean metrics),
                                 the estimates of the time left, resume and stop reasons
    logs/<tag>/...               TorchRL logger output (CSV by default; TensorBoard / W&B on request)
    eval/metrics.csv             one row per (evaluation, context): every metric
    eval/episodes.csv            one row per (evaluation, context, weight, episode): returns by objective
    eval/sorl.csv                one row per (evaluation, context, weight): the f_SORL return (the
                                 domain's original scalar reward), undiscounted and discounted, and
                                 which weight was the context's best (absent if the env has none)
    fronts/frames_<N>.csv        the Pareto front of every context at that evaluation
    train/episodes.csv           one row per finished training episode: context, preference, returns
    train/losses.csv             the losses, ε / α and frames per second, every 50 updates
    report.md, report_*.png      the last evaluation against the specialists (and published baselines)
    reevaluation/...             the same eval/, fronts/ and report written by ``morl-trl evaluate``

Nothing is averaged over objectives: every column names its objective.

On resume, :meth:`RunLog.truncate` first cuts every log back to the checkpoint's frame (rows
of the CSVs above it, fronts files after it, the TorchRL CSV logger's scalar rows above it),
so that a resumed run's files are those of an uninterrupted run. TensorBoard event files and
W&B runs cannot be cut: after a resume they keep what the killed process wrote past the
checkpoint (the resumed values are logged again at the same steps).
"""

from __future__ import annotations

import csv
import math
import time
from pathlib import Path

from tqdm.auto import tqdm

from morl_trl.runs.atomic import atomic_write, atomic_write_bytes, disk_error
from morl_trl.runs.nofollow import check_no_links, open_nofollow


__all__ = ["RunLog", "check_logger"]


def _append_rows(path: Path, rows: list[dict], root: Path | None = None) -> None:
    if not rows:
        return
    check_no_links(path, root)
    path.parent.mkdir(parents=True, exist_ok=True)
    new = not path.exists()
    keys = list(dict.fromkeys(k for r in rows for k in r))
    if not new:
        with path.open() as fh:
            header = next(csv.reader(fh), [])
        keys = header + [k for k in keys if k not in header]
        if len(keys) > len(header):  # new columns (e.g. a metric that appeared): rewrite with the wider header
            with path.open() as fh:
                old = list(csv.DictReader(fh))
            rows = old + rows
            new = True
    if new:  # a whole file (the first rows, or all rows under a wider header): atomically
        def write(fh) -> None:
            w = csv.DictWriter(fh, fieldnames=keys)
            w.writeheader()
            w.writerows(rows)

        atomic_write(path, write, mode="w", newline="", root=root)
        return
    try:
        with open_nofollow(path, "a", root=root, newline="") as fh:  # (a line cut by a kill is dropped on resume)
            csv.DictWriter(fh, fieldnames=keys).writerows(rows)
    except OSError as err:
        raise disk_error(err, str(path)) from err


def _cut_lines(path: Path, frames: int, *, header: bool) -> int:
    """Keep the lines of ``path`` whose first comma-separated field (a frame or step count) is
    ``<= frames`` (and the header line); rewritten atomically, bytes of kept lines unchanged.
    Returns the number of lines removed."""
    data = path.read_bytes()
    lines = data.splitlines(keepends=True)
    keep, removed = [], 0
    for i, line in enumerate(lines):
        if header and i == 0:
            keep.append(line)
            continue
        first = line.split(b",", 1)[0].strip()
        try:
            step = int(float(first))
        except ValueError:
            keep.append(line)
            continue
        if step <= frames:
            keep.append(line)
        else:
            removed += 1
    if removed or (lines and not lines[-1].endswith(b"\n")):
        if keep and not keep[-1].endswith(b"\n"):  # a line cut mid-write by a kill
            keep.pop()
            removed += 1
        atomic_write_bytes(path, b"".join(keep))
    return removed


def check_logger(kind: str) -> None:
    """``ValueError`` unless ``kind`` is a logger this machine can write (before anything is written)."""
    if kind in ("", "none", None, "csv"):
        return
    needs = {"tensorboard": "tensorboard", "wandb": "wandb"}
    if kind not in needs:
        raise ValueError(f"unknown logger {kind!r}; valid: csv, tensorboard, wandb, none")
    import importlib.util

    if importlib.util.find_spec(needs[kind]) is None:
        raise ValueError(f"logger {kind!r} needs the {needs[kind]!r} package; install it or use logger='csv'")


def _make_logger(kind: str, run_dir: Path, tag: str):
    from torchrl.record.loggers import get_logger

    check_logger(kind)
    if kind in ("", "none", None):
        return None
    return get_logger(kind, logger_name=str(run_dir / "logs"), experiment_name=tag)


class RunLog:
    """Writes a run's metrics, fronts, training episodes and final report (see the module docstring)."""

    #: the longest training episodes wait in memory before they are appended to ``train/episodes.csv``
    FLUSH_SECONDS = 2.0
    #: what :meth:`report` prints: its tables (``morl-trl train``, ``evaluate``) or, ``False``,
    #: its one-line summary (``morl_trl.train``)
    echo_report = True

    def __init__(self, run_dir, cfg, spec, tag: str = "train") -> None:
        self.run_dir = Path(run_dir)
        self.cfg = cfg
        self.spec = spec
        self.tag = tag
        self.objectives = tuple(spec.objective_names)
        self.logger = _make_logger(cfg.logger, self.run_dir, tag)
        # a re-evaluation (morl-trl evaluate) writes beside the run's own outputs, not over them
        self.out_dir = self.run_dir if tag == "train" else self.run_dir / tag
        self.last_result = None
        self._episode_rows: list[dict] = []  # training episodes not yet in train/episodes.csv (flush)
        self._flushed_at = time.monotonic()

    # ------------------------------------------------------------------ resume
    def truncate(self, frames: int) -> int:
        """Cut every log back to ``frames`` (a checkpoint's): rows of ``eval/*.csv``,
        ``train/episodes.csv`` and the TorchRL CSV logger's scalars above it, fronts files after
        it. Returns the number of rows and files removed. TensorBoard / W&B output is left."""
        removed = 0
        for rel in ("eval/metrics.csv", "eval/episodes.csv", "eval/sorl.csv", "train/episodes.csv", "train/losses.csv"):
            path = self.run_dir / rel
            if path.is_file():
                removed += _cut_lines(path, frames, header=True)
        fronts = self.run_dir / "fronts"
        if fronts.is_dir():
            for f in fronts.glob("frames_*.csv"):
                if int(f.stem.split("_")[-1]) > frames:
                    f.unlink()
                    removed += 1
        scalars = self.run_dir / "logs" / self.tag / "scalars"
        if scalars.is_dir():
            for f in scalars.rglob("*.csv"):
                removed += _cut_lines(f, frames, header=False)
        return removed

    # ------------------------------------------------------------------ notes
    def note(self, message: str) -> None:
        line = f"{time.strftime('%Y-%m-%d %H:%M:%S')} {message}"
        with open_nofollow(self.run_dir / "log.txt", "a", root=self.run_dir) as fh:
            fh.write(line + "\n")
        tqdm.write(message)  # above a progress bar, never through it

    def _scalar(self, name: str, value: float, step: int) -> None:
        if self.logger is not None and value is not None and math.isfinite(value):
            self.logger.log_scalar(name, float(value), step=step)

    # ------------------------------------------------------------------ training
    def losses(self, frames: int, losses, **extra: float) -> None:
        """Log the scalar losses (and ``extra`` scalars: frames per second, ε, α) to the TorchRL
        logger and as a row of ``train/losses.csv`` (the report's training curves)."""
        row: dict = {"frames": frames}
        for key, value in losses.items():
            if value.numel() == 1:
                row[key] = value.item()
                self._scalar(f"train/{key}", row[key], frames)
        for key, value in extra.items():
            if value is not None and math.isfinite(value):
                row[key] = float(value)
                self._scalar(f"train/{key}", row[key], frames)
        _append_rows(self.out_dir / "train" / "losses.csv", [row], self.run_dir)
        self.flush()

    def training_episodes(self, frames: int, batch) -> None:
        """Record the returns of the episodes that ended in this batch (needs DiscountedVectorReturn).

        The rows of ``train/episodes.csv`` are held in memory and appended together (:meth:`flush`:
        with the losses every 50 updates, at least every :attr:`FLUSH_SECONDS`, before every
        evaluation, checkpoint and report, and on close): a one-env run ends an episode every
        few frames, and a file append per episode cost more than the frame itself."""
        nxt = batch.get("next")
        done = nxt.get("done").squeeze(-1)
        if not done.any() or "episode_return" not in nxt.keys():
            return
        if bool(done.all()):  # (x[done] of every row: the rows as they are, without a masked copy)
            def ended(x):
                return x.reshape(done.numel(), *x.shape[done.ndim:]).cpu()
        else:
            def ended(x):
                return x[done].cpu()
        ret = ended(nxt["episode_return"])
        disc = ended(nxt["episode_discounted_return"])
        pref = ended(batch.get("preference")) if "preference" in batch.keys() else None
        ctx = ended(batch.get("context")) if "context" in batch.keys() else None
        columns = []  # (names, rows of values) per group of columns, in the file's order
        if ctx is not None:
            columns.append(([f"context_{n}" for n in self.spec.context_space.names], ctx.tolist()))
        if pref is not None:
            columns.append(([f"preference_{o}" for o in self.objectives], pref.tolist()))
        columns.append(([f"return_{o}" for o in self.objectives], ret.tolist()))
        columns.append(([f"discounted_return_{o}" for o in self.objectives], disc.tolist()))
        for i in range(ret.shape[0]):
            row = {"frames": frames}
            for names, values in columns:
                row.update(zip(names, map(float, values[i])))
            self._episode_rows.append(row)
        if time.monotonic() - self._flushed_at >= self.FLUSH_SECONDS:
            self.flush()
        one = columns[-2][1][0] if ret.shape[0] == 1 else None  # (one episode: the mean is its value, exactly)
        for j, o in enumerate(self.objectives):
            self._scalar(f"train/episode_return/{o}", float(ret[:, j].mean()) if one is None else one[j], frames)

    def flush(self) -> None:
        """Append the training episodes held in memory to ``train/episodes.csv``."""
        rows, self._episode_rows = self._episode_rows, []
        self._flushed_at = time.monotonic()
        _append_rows(self.run_dir / "train" / "episodes.csv", rows, self.run_dir)

    # ------------------------------------------------------------------ evaluation
    def evaluation(self, frames: int, result) -> dict:
        """Log one :class:`~morl_trl.evaluation.EvaluationResult`; returns a small summary."""
        self.flush()
        self.last_result = result
        rows = [{"frames": frames, **r} for r in result.metric_rows()]
        _append_rows(self.out_dir / "eval" / "metrics.csv", rows, self.run_dir)
        _append_rows(self.out_dir / "eval" / "episodes.csv", [{"frames": frames, **r} for r in result.to_rows()],
                     self.run_dir)
        _append_rows(self.out_dir / "eval" / "sorl.csv", [{"frames": frames, **r} for r in result.sorl_rows()],
                     self.run_dir)
        fronts = self.out_dir / "fronts" / f"frames_{frames:012d}.csv"
        check_no_links(fronts, self.run_dir)
        result.write_csv(fronts, kind="fronts")
        for name, value in result.summary(prefix=f"{self.tag}_eval").items():
            self._scalar(name, value, frames)
        nhgr = result.aggregate.get("nhgr")
        return {
            "frames": frames,
            "nhgr_mean": float(nhgr) if nhgr is not None else float("nan"),
            "aggregate": dict(result.aggregate),
            "per_context": {c: dict(r.metrics) for c, r in result.per_context.items()},
        }

    # ------------------------------------------------------------------ report
    def report(self, summary: dict, fps: float | None) -> Path:
        """Write ``report.md`` and plots for the last evaluation; print the NHGR table."""
        from morl_trl.reporting.report import write_report

        self.flush()  # (its training curves read train/episodes.csv)
        check_no_links(self.out_dir / "report.md", self.run_dir)
        for p in self.out_dir.glob("*report*"):  # (report.md, report_*.png, report_floors.json and their temporaries)
            check_no_links(p, self.run_dir)
        return write_report(self, summary, fps)

    def report_stop(self, message: str) -> None:
        """Add a line saying why the run stopped early to ``report.md`` (created if missing)."""
        path = self.out_dir / "report.md"
        with open_nofollow(path, "a", root=self.run_dir) as fh:
            fh.write(f"\n**Run stopped early.** {message}\n")

    def close(self) -> None:
        try:
            self.flush()
        except OSError:  # (a full disk: what a resume keeps was flushed before the last checkpoint)
            pass
        if self.logger is not None and hasattr(self.logger, "experiment"):
            exp = self.logger.experiment
            if hasattr(exp, "close"):
                try:
                    exp.close()
                except Exception:  # noqa: BLE001 - closing a logger must not hide the run's own error
                    pass
