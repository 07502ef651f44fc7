"""The setpoint watchdog: when the event loop stops producing setpoints, command zero velocity from outside it.

MAVSDK re-sends the last offboard setpoint at 20 Hz from its own thread, so while our process lives PX4's
offboard-loss failsafe never fires: a stalled event loop (a blocked call, a swap storm, a debugger) would
leave the vehicle flying the last velocity. The watchdog is fed with every setpoint the loop sends; when
none came for ``timeout_s`` while we own offboard, it calls ``fire`` once — the vehicle adapter replaces
the setpoint being re-sent with zero velocity, from the watchdog's thread, without the event loop. It
re-arms with the next setpoint the loop sends.

``SetpointWatchdog`` is the decision (fed and polled with times, no thread); ``WatchdogThread`` polls it
on the monotonic clock in a daemon thread (the MAVSDK adapter starts one). The in-process simulator
polls it from its physics steps instead, on the simulated world's clock, so the same decision runs in
virtual time.
"""

from __future__ import annotations

import threading
from collections.abc import Callable

POLL_PERIOD_S = 0.02


class SetpointWatchdog:
    """Fire once when no setpoint was fed for ``timeout_s`` while engaged. Thread-safe."""

    def __init__(self, timeout_s: float, fire: Callable[[float, float], None]) -> None:
        """``fire(now_s, silent_s)`` is called from the polling thread."""
        self.timeout_s = timeout_s
        self._fire = fire
        self._lock = threading.Lock()
        self._engaged = False
        self._last_feed_s: float | None = None
        self._fired = False
        self.fired_count = 0

    def engage(self, now_s: float) -> None:
        with self._lock:
            self._engaged, self._last_feed_s, self._fired = True, now_s, False

    def disengage(self) -> None:
        with self._lock:
            self._engaged = False

    @property
    def engaged(self) -> bool:
        return self._engaged

    def feed(self, now_s: float) -> None:
        with self._lock:
            self._last_feed_s, self._fired = now_s, False

    def poll(self, now_s: float) -> bool:
        """Check at ``now_s``; True when it fired now."""
        with self._lock:
            last = self._last_feed_s
            if not self._engaged or self._fired or last is None or now_s - last <= self.timeout_s:
                return False
            self._fired = True
            self.fired_count += 1
        self._fire(now_s, now_s - last)
        return True


class WatchdogThread:
    """Polls a watchdog every ``period_s`` on ``now_s`` (the loop's monotonic clock, read off the loop)."""

    def __init__(self, watchdog: SetpointWatchdog, now_s: Callable[[], float], period_s: float = POLL_PERIOD_S):
        self._watchdog = watchdog
        self._now_s = now_s
        self._period_s = period_s
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="offboard.watchdog", daemon=True)

    def start(self) -> None:
        self._thread.start()

    def stop(self) -> None:
        self._stop.set()
        if self._thread.is_alive():
            self._thread.join(timeout=1.0)

    def _run(self) -> None:
        while not self._stop.wait(self._period_s):
            self._watchdog.poll(self._now_s())
