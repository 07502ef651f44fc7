"""The simulator's state log: JSON lines, flushed as written, for end-to-end tests and reports.

Every line has ``t_wall`` (``time.time()`` of the writer, seconds since the epoch), ``t_s`` (seconds
since the simulated autopilot booted) and ``event``. Events written by ``sim.autopilot``:

- ``start``: profile, seed, home, addresses;  ``stop``.
- ``mode``: ``mode`` (MAVSDK FlightMode name, e.g. "HOLD", "POSCTL", "OFFBOARD"), ``autopilot_mode``
  (e.g. "AUTO.LOITER", "BRAKE"), ``reason`` ("boot", "command", "pilot", "offboard_loss",
  "takeoff_done", "landed").
- ``armed``: ``armed`` (bool), ``reason`` ("command", "force" (disarm with 21196), "auto_disarm_land",
  "auto_disarm_preflight").
- ``landed_state``: ``landed_state`` ("ON_GROUND", "TAKING_OFF", "IN_AIR", "LANDING").
- ``statustext``: ``text``, ``severity`` (MAV_SEVERITY).
- ``command``: ``command`` (MAV_CMD name without the prefix, e.g. "DO_SET_MODE"), ``result`` (MAV_RESULT
  name, e.g. "ACCEPTED", "DENIED"), ``source`` ("link" = MAVSDK's port, "pilot"), ``params`` (NaN → null).
- ``setpoint``: every SET_POSITION_TARGET_LOCAL_NED received (MAVSDK's 20 Hz re-sends included):
  ``vel_ned_mps``, ``yaw_rad``, ``type_mask``, ``frame``, ``mode`` (the mode it arrived in). The in-process
  vehicle (``sim.inproc``) writes the same record with ``origin`` (app, resend, watchdog) instead.
- ``param``: ``name``, ``value``.   ``home``: ``home_ned_m``.   ``gripper``: ``action``.
- ``truth`` at 10 Hz: ``pos_ned_m``, ``vel_ned_mps``, ``att_rad`` (roll, pitch, yaw), ``mode``,
  ``armed``, ``landed_state``, ``wind_ned_mps``, ``battery_v``, ``battery_remaining``.
"""

from __future__ import annotations

import json
import math
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import IO, Any


def _clean(value: Any) -> Any:
    """Floats rounded to 7 decimals (1 cm in latitude); NaN/inf become null (JSON has neither)."""
    if isinstance(value, float):
        return round(value, 7) if math.isfinite(value) else None
    if isinstance(value, (tuple, list)):
        return [_clean(v) for v in value]
    return value


class StateLog:
    """Appends one JSON object per line and flushes it at once, so a crash loses nothing."""

    def __init__(self, path: str | Path, wall_clock: Callable[[], float] = time.time) -> None:
        self.path = Path(path)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self._file: IO[str] | None = self.path.open("a", encoding="utf-8")
        self._wall_clock = wall_clock

    def write(self, event: str, t_s: float, **fields: Any) -> None:
        if self._file is None:
            return
        record = {"t_wall": round(self._wall_clock(), 4), "t_s": round(t_s, 4), "event": event}
        record.update({k: _clean(v) for k, v in fields.items()})
        self._file.write(json.dumps(record) + "\n")
        self._file.flush()

    def close(self) -> None:
        if self._file is not None:
            self._file.close()
            self._file = None


def read_state_log(path: str | Path) -> Iterator[dict[str, Any]]:
    """The records of a state log (a partial last line, from a writer still running, is skipped)."""
    with Path(path).open(encoding="utf-8") as f:
        for line in f:
            try:
                yield json.loads(line)
            except json.JSONDecodeError:
                continue
