"""The autopilot's sample times on the loop clock.

A MAVLink sample carries the autopilot's ``time_boot_ms`` from when it was taken; the app receives it some
milliseconds later, more when the companion computer is busy (a stalled event loop receives a whole burst
of queued samples at once). Stamping with the receipt time turns that delay into position error: 45 ms at
1 m/s is 4.5 cm, as large as the whole tracking budget. ``RemoteClock`` maps the autopilot's time onto
the loop clock passively, without PX4's TIMESYNC exchange (ArduPilot and the simulator need not answer):

    offset(r) = min over the window of (o_i + rate · (r − r_i)),   o_i = t_received,i − r_i

where ``rate`` is the drift of the offset, measured between the least-delayed packets of older and newer
parts of the window. The least-delayed packet bounds the true offset by its transport delay (well under a
millisecond on UDP or serial), so ``r + offset(r)`` is the sample time on the loop clock; it is never later
than the receipt time.

Only a clock that runs in real time can be mapped this way. A crystal drifts by some 10⁻⁴; PX4 SITL in
lockstep runs at the simulator's real-time factor, which is rarely exactly 1 and varies. When the measured
rate is off by more than ``max_rate_error`` — and until it has been measured, for the first
``3/4 · window_s`` — samples keep their receipt time (``mode`` says which is in use). A clock that runs
backwards (the autopilot rebooted) starts everything afresh.
"""

from __future__ import annotations

import math
from collections import deque

from app.stats import percentile

AUTOPILOT = "autopilot"
RECEIPT = "receipt"


class RemoteClock:
    def __init__(
        self,
        window_s: float = 10.0,
        max_rate_error: float = 2e-3,
        reboot_jump_s: float = 1.0,
        keep_latencies: int = 100_000,
    ) -> None:
        self.bucket_s = window_s / 4.0
        self.max_rate_error = max_rate_error
        self.reboot_jump_s = reboot_jump_s
        # Per bucket of remote time: (bucket index, remote time of the least-delayed packet, its offset).
        self._buckets: deque[tuple[int, float, float]] = deque(maxlen=5)
        self._last_remote_s: float | None = None
        self.rate: float | None = None  # d(offset)/d(remote time), once measured
        self.resets = 0
        self.latencies_s: deque[float] = deque(maxlen=keep_latencies)

    @property
    def mode(self) -> str:
        return AUTOPILOT if self.rate is not None and abs(self.rate) <= self.max_rate_error else RECEIPT

    def stamp(self, remote_s: float, received_s: float) -> float:
        """Loop time at which a sample stamped ``remote_s`` by the autopilot was taken."""
        if self._last_remote_s is not None and remote_s < self._last_remote_s - self.reboot_jump_s:
            self._buckets.clear()
            self.rate = None
            self.resets += 1
        self._last_remote_s = remote_s
        self._add(remote_s, received_s - remote_s)
        if self.mode != AUTOPILOT:
            return received_s
        assert self.rate is not None
        offset_s = min(o + self.rate * (remote_s - r) for _, r, o in self._buckets)
        t_s = min(received_s, remote_s + offset_s)
        self.latencies_s.append(received_s - t_s)
        return t_s

    def _add(self, remote_s: float, offset_s: float) -> None:
        k = math.floor(remote_s / self.bucket_s)
        last = self._buckets[-1] if self._buckets else None
        if last is not None and last[0] == k:
            if offset_s < last[2]:
                self._buckets[-1] = (k, remote_s, offset_s)
            return
        if last is not None and last[0] > k:  # out of order across a bucket edge: the newer bucket stands
            return
        if last is not None and k - last[0] > 1:  # a gap in the stream: measure afresh
            self._buckets.clear()
            self.rate = None
        self._buckets.append((k, remote_s, offset_s))
        complete = list(self._buckets)[:-1]
        if len(complete) >= 3:
            (_, r0, o0), (_, r1, o1) = complete[0], complete[-1]
            self.rate = (o1 - o0) / (r1 - r0)

    def summary(self, prefix: str) -> dict[str, float | str | None]:
        """Which time the samples carry, and how late they arrived after it (seconds)."""
        xs = sorted(self.latencies_s)
        return {
            f"{prefix}_clock": self.mode,
            f"{prefix}_clock_rate_error": self.rate,
            f"{prefix}_latency_p50_s": percentile(xs, 0.50),
            f"{prefix}_latency_p95_s": percentile(xs, 0.95),
            f"{prefix}_latency_max_s": xs[-1] if xs else None,
        }
