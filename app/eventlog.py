"""The run's event log: one JSON object per line, written by a thread so the event loop never waits on disk.

Every line has ``t_s`` (loop clock) and ``kind`` (``state``, ``command``, ``setpoint``, ``vehicle``, ``run``).
``write`` only cleans the fields and puts the record on a bounded queue; the writer thread encodes and
writes it. Nothing is dropped: when the queue is full (the disk stalls for seconds) ``write`` waits for
room — the setpoint watchdog, a thread of its own, keeps the vehicle safe meanwhile. The file is flushed
after every ``state`` and ``run`` record and whenever the queue runs empty, and ``close`` writes everything
still queued before it returns, so a clean exit loses nothing and a crash loses at most the records of
the last moments. ``write`` may be called from any thread (the watchdog logs through it). ``subscribe``
hands the records of some kinds to a listener as they are written (the ground station's events).
"""

from __future__ import annotations

import json
import math
import queue
import threading
from collections.abc import Callable, Collection
from pathlib import Path
from typing import IO, Any

QUEUE_SIZE = 20_000  # records; ~7 minutes of 50 Hz setpoint decisions
FLUSH_KINDS = frozenset({"state", "run"})
_STOP = object()


def _clean(value: Any) -> Any:
    if isinstance(value, float):
        return round(value, 4) if math.isfinite(value) else None
    if isinstance(value, (list, tuple)):
        return [_clean(v) for v in value]
    if isinstance(value, dict):
        return {k: _clean(v) for k, v in value.items()}
    return value


class EventLog:
    def __init__(self, path: Path | None, queue_size: int = QUEUE_SIZE) -> None:
        self.path = path
        self.counts: dict[str, int] = {}
        self.written = 0  # records the writer thread has written to the file
        self._lock = threading.Lock()
        self._queue: queue.Queue[Any] = queue.Queue(maxsize=queue_size)
        self._file: IO[str] | None = path.open("a", buffering=1 << 16) if path else None
        self._thread: threading.Thread | None = None
        self._listeners: tuple[tuple[frozenset[str], Callable[[dict[str, Any]], None]], ...] = ()
        if self._file is not None:
            self._thread = threading.Thread(target=self._writer, name="eventlog.writer", daemon=True)
            self._thread.start()

    def subscribe(self, kinds: Collection[str], listener: Callable[[dict[str, Any]], None]) -> None:
        """Hand every record of ``kinds`` to ``listener`` as it is written, on the thread that writes it (a listener
        must be quick and must not write to this log)."""
        with self._lock:
            self._listeners = (*self._listeners, (frozenset(kinds), listener))

    def write(self, t_s: float, kind: str, **fields: Any) -> None:
        with self._lock:
            self.counts[kind] = self.counts.get(kind, 0) + 1
            listeners = self._listeners
        wanted = [listener for kinds, listener in listeners if kind in kinds]
        if self._thread is None and not wanted:
            return  # nobody reads this record: it is only counted
        record = {"t_s": round(t_s, 4), "kind": kind, **_clean(fields)}
        for listener in wanted:
            listener(record)
        if self._thread is not None:
            self._queue.put(record)

    def total(self) -> int:
        """Records written so far (all kinds)."""
        with self._lock:
            return sum(self.counts.values())

    def close(self) -> None:
        """Write everything still queued, then close the file (idempotent)."""
        if self._thread is not None:
            self._queue.put(_STOP)
            self._thread.join()
            self._thread = None

    def _writer(self) -> None:
        f = self._file
        assert f is not None
        while True:
            record = self._queue.get()
            if record is _STOP:
                break
            f.write(json.dumps(record, separators=(",", ":")) + "\n")
            self.written += 1
            if record["kind"] in FLUSH_KINDS or self._queue.empty():
                f.flush()
        f.flush()
        f.close()
        self._file = None
