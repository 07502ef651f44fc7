"""The autopilot's sample times on the loop clock.

A MAVLink sample carries the autopilot's ``time_boot_ms`` from when it was taken; the app receives it some
milliseconds later, more when the companion computer is busy (a stalled event loop stamps a whole burst of
queued samples with the same late time). Stamping with the receipt time turns that delay into position
error: 45 ms at 1 m/s is 4.5 cm, as large as the whole tracking budget. ``RemoteClock`` maps the
autopilot's time onto the loop clock passively, without PX4's TIMESYNC exchange (ArduPilot and the
simulator need not answer it):

    offset = min over the last ``window_s`` of (t_received − t_remote)

The least-delayed packet of the window bounds the true offset from above by its transport delay (well
under a millisecond on a UDP or serial link), so ``t_remote + offset`` is the sample time on the loop
clock. It is never later than the receipt time. A sliding window follows the drift of the two crystals;
a clock that runs backwards (the autopilot rebooted) starts the estimate afresh.
"""

from __future__ import annotations

from collections import deque

from app.stats import percentile


class RemoteClock:
    def __init__(self, window_s: float = 10.0, reboot_jump_s: float = 1.0, keep_latencies: int = 100_000) -> None:
        self.window_s = window_s
        self.reboot_jump_s = reboot_jump_s
        # (received_s, offset_s) with offsets increasing front to back: the front is the window's minimum.
        self._window: deque[tuple[float, float]] = deque()
        self._last_remote_s: float | None = None
        self.resets = 0
        self.latencies_s: deque[float] = deque(maxlen=keep_latencies)

    def stamp(self, remote_s: float, received_s: float) -> float:
        """Loop time at which a sample stamped ``remote_s`` by the autopilot was taken."""
        if self._last_remote_s is not None and remote_s < self._last_remote_s - self.reboot_jump_s:
            self._window.clear()
            self.resets += 1
        self._last_remote_s = remote_s
        offset_s = received_s - remote_s
        while self._window and self._window[-1][1] >= offset_s:
            self._window.pop()
        self._window.append((received_s, offset_s))
        while self._window[0][0] < received_s - self.window_s:
            self._window.popleft()
        t_s = min(received_s, remote_s + self._window[0][1])
        self.latencies_s.append(received_s - t_s)
        return t_s

    def latency_summary(self, prefix: str) -> dict[str, float | None]:
        """Receipt delay of the samples stamped so far (beyond the best of their window), seconds."""
        xs = sorted(self.latencies_s)
        return {
            f"{prefix}_latency_p50_s": percentile(xs, 0.50),
            f"{prefix}_latency_p95_s": percentile(xs, 0.95),
            f"{prefix}_latency_max_s": xs[-1] if xs else None,
        }
