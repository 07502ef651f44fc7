"""The run's event log: one JSON object per line, flushed as written, so a crash loses nothing.

Every line has ``t_s`` (loop clock) and ``kind`` (``state``, ``command``, ``setpoint``, ``vehicle``, ``run``).
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import IO, Any


def _clean(value: Any) -> Any:
    if isinstance(value, float):
        return round(value, 4) if math.isfinite(value) else None
    if isinstance(value, (list, tuple)):
        return [_clean(v) for v in value]
    if isinstance(value, dict):
        return {k: _clean(v) for k, v in value.items()}
    return value


class EventLog:
    def __init__(self, path: Path | None) -> None:
        self.path = path
        self._file: IO[str] | None = path.open("a", buffering=1) if path else None
        self.counts: dict[str, int] = {}

    def write(self, t_s: float, kind: str, **fields: Any) -> None:
        self.counts[kind] = self.counts.get(kind, 0) + 1
        if self._file is None:
            return
        line = {"t_s": round(t_s, 4), "kind": kind, **_clean(fields)}
        self._file.write(json.dumps(line, separators=(",", ":")) + "\n")
        self._file.flush()

    def close(self) -> None:
        if self._file is not None:
            self._file.close()
            self._file = None
