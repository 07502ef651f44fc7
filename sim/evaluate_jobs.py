"""Many evaluation runs (``sim.evaluate_pickup.run_pickup``) on local processes or a Dask cluster, and the progress
bar that follows them."""

from __future__ import annotations

import concurrent.futures
import sys
import time
from collections.abc import Callable, Iterator, Sequence
from typing import Any

from sim.evaluate_pickup import RunInputs, run_pickup

Job = tuple[dict[str, Any], str, int, str | None, RunInputs | None]  # (scenario, config, run, run dir, inputs)


def run_jobs(
    jobs: Sequence[Job],
    processes: int,
    dask_address: str | None = None,
    progress: Callable[[dict[str, Any]], None] | None = None,
) -> list[dict[str, Any]]:
    """Every job's result, in the order of ``jobs``: on ``processes`` local processes (1: in this one), or on the
    Dask cluster at ``dask_address`` (a ``dask.distributed`` scheduler, e.g. ``tcp://host:8786``)."""
    results: list[dict[str, Any] | None] = [None] * len(jobs)
    for i, r in _completed(jobs, processes, dask_address):
        results[i] = r
        if progress is not None:
            progress(r)
    return [r for r in results if r is not None]


def _completed(jobs: Sequence[Job], processes: int, dask_address: str | None) -> Iterator[tuple[int, dict[str, Any]]]:
    if dask_address is not None:
        from dask.distributed import Client, as_completed

        with Client(dask_address) as client:
            futures = [client.submit(run_pickup, *job, pure=False) for job in jobs]
            index = {f.key: i for i, f in enumerate(futures)}
            for f in as_completed(futures):
                yield index[f.key], f.result()
        return
    if processes <= 1:
        for i, job in enumerate(jobs):
            yield i, run_pickup(*job)
        return
    with concurrent.futures.ProcessPoolExecutor(processes) as pool:
        pending = {pool.submit(run_pickup, *job): i for i, job in enumerate(jobs)}
        for f in concurrent.futures.as_completed(pending):
            yield pending[f], f.result()


class Progress:
    """A one-line progress bar on stderr: runs done, picked up, runs per second, time left."""

    def __init__(self, total: int, stream: Any = None, width: int = 30) -> None:
        self.total, self.done, self.ok = total, 0, 0
        self.stream = stream if stream is not None else sys.stderr
        self.width = width
        self.t0 = time.perf_counter()
        self.tty = bool(getattr(self.stream, "isatty", lambda: False)())
        self._last_pct = -1

    def __call__(self, result: dict[str, Any]) -> None:
        self.done += 1
        self.ok += result["outcome"] == "picked_up"
        elapsed_s = time.perf_counter() - self.t0
        rate = self.done / elapsed_s if elapsed_s > 0 else 0.0
        left_s = (self.total - self.done) / rate if rate > 0 else 0.0
        filled = self.width * self.done // max(self.total, 1)
        line = (
            f"[{'#' * filled}{'.' * (self.width - filled)}] {self.done}/{self.total} runs, {self.ok} picked up, "
            f"{rate:.2f} runs/s, {elapsed_s:.0f} s, ~{left_s:.0f} s left"
        )
        pct = 100 * self.done // max(self.total, 1)
        if self.tty:
            self.stream.write("\r" + line + ("\n" if self.done == self.total else ""))
        elif pct // 10 != self._last_pct // 10 or self.done == self.total:  # a line per 10 % when not a terminal
            self.stream.write(line + "\n")
        self._last_pct = pct
        self.stream.flush()
