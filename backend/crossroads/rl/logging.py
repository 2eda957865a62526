"""Training metrics: ``metrics.csv`` (always), TensorBoard events (when available), a progress bar.

Metric names are namespaced as cleanrl does: ``losses/J_v``, ``losses/J_track``, ``losses/J_safe``,
``losses/J_pi`` (means over the iterations since the previous row), ``charts/TAR`` and its companions,
``charts/iterations_per_s``, ``charts/lr_*``, ``buffer/*``. One CSV row per logging step, keyed by
``iteration`` (the number of iterations done). On resume, rows beyond the checkpoint's iteration are
dropped so the file continues exactly as the uninterrupted run's.
"""

from __future__ import annotations

import csv
import sys
import time
from pathlib import Path
from typing import Any, TextIO

COLUMNS: tuple[str, ...] = (
    "iteration", "losses/J_v", "losses/J_track", "losses/J_safe", "losses/J_pi",
    "charts/TAR", "charts/TAR_std", "charts/TAR_steps", "charts/TAR_collisions", "charts/TAR_off_road",
    "charts/TAR_passed", "charts/iterations_per_s", "charts/lr_policy", "charts/lr_value",
    "charts/lr_adversary", "charts/saturated_share", "buffer/size", "buffer/added", "time/elapsed_s",
)
TIMING_COLUMNS = ("charts/iterations_per_s", "time/elapsed_s")  # the only columns that differ run to run


class MetricsLogger:
    """Appends rows to ``run_dir/metrics.csv``; mirrors them to TensorBoard when it can."""

    def __init__(self, run_dir: Path, *, resume_iteration: int | None = None, tensorboard: bool = True) -> None:
        self.path = Path(run_dir) / "metrics.csv"
        if resume_iteration is not None and self.path.exists():
            with self.path.open(newline="") as f:
                rows = [r for r in csv.DictReader(f) if int(r["iteration"]) <= resume_iteration]
            self._write_header()
            with self.path.open("a", newline="") as f:  # columns since dropped are left out
                w = csv.DictWriter(f, fieldnames=COLUMNS, extrasaction="ignore")
                w.writerows(rows)
        else:
            self._write_header()
        self.writer: Any = None
        if tensorboard:
            try:
                from torch.utils.tensorboard import SummaryWriter

                self.writer = SummaryWriter(str(Path(run_dir) / "tb"), purge_step=resume_iteration)
            except ImportError:  # tensorboard not installed: CSV only
                self.writer = None

    def _write_header(self) -> None:
        with self.path.open("w", newline="") as f:
            csv.DictWriter(f, fieldnames=COLUMNS).writeheader()

    def log(self, row: dict[str, float]) -> None:
        unknown = set(row) - set(COLUMNS)
        if unknown:
            raise KeyError(f"unknown metric(s) {sorted(unknown)}")
        with self.path.open("a", newline="") as f:
            csv.DictWriter(f, fieldnames=COLUMNS).writerow({k: row.get(k, "") for k in COLUMNS})
        if self.writer is not None:
            step = int(row["iteration"])
            for k, v in row.items():
                if k != "iteration" and v is not None and v == v:
                    self.writer.add_scalar(k, float(v), step)
            self.writer.flush()

    def close(self) -> None:
        if self.writer is not None:
            self.writer.close()


def read_metrics(run_dir: Path) -> dict[str, list[float]]:
    """``metrics.csv`` of a run as columns of floats (NaN where empty)."""
    with (Path(run_dir) / "metrics.csv").open(newline="") as f:
        rows = list(csv.DictReader(f))
    return {k: [float(r[k]) if r.get(k) not in (None, "") else float("nan") for r in rows] for k in COLUMNS}


class Progress:
    """A progress bar with rate and ETA: tqdm when installed, else a plain one on stderr."""

    def __init__(self, total: int, initial: int = 0, enabled: bool = True, stream: TextIO | None = None) -> None:
        self.total, self.n, self.enabled = total, initial, enabled
        self.stream = stream or sys.stderr
        self._start, self._start_n, self._last = time.monotonic(), initial, 0.0
        self._bar: Any = None
        self.postfix = ""
        if enabled:
            try:
                from tqdm import tqdm

                self._bar = tqdm(total=total, initial=initial, unit="it", dynamic_ncols=True)
            except ImportError:
                self._bar = None

    def update(self, n: int = 1, postfix: str | None = None) -> None:
        self.n += n
        if postfix is not None:
            self.postfix = postfix
        if not self.enabled:
            return
        if self._bar is not None:
            self._bar.update(n)
            if postfix is not None:
                self._bar.set_postfix_str(postfix)
            return
        now = time.monotonic()
        if now - self._last < 1.0 and self.n < self.total:
            return
        self._last = now
        rate = (self.n - self._start_n) / max(now - self._start, 1e-9)
        eta = (self.total - self.n) / rate if rate > 0 else float("inf")
        width = 30
        done = int(width * self.n / max(self.total, 1))
        eta_text = time.strftime("%H:%M:%S", time.gmtime(eta)) if eta != float("inf") else "--:--:--"
        self.stream.write(f"\r[{'#' * done}{'.' * (width - done)}] {self.n}/{self.total} "
                          f"{rate:.2f} it/s ETA {eta_text} {self.postfix}")
        self.stream.flush()

    def close(self) -> None:
        if self._bar is not None:
            self._bar.close()
        elif self.enabled:
            self.stream.write("\n")
            self.stream.flush()
