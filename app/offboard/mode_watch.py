"""Who has the vehicle: our mode commands against the flight modes telemetry shows. Pure.

A *takeover* is a change of flight mode that we did not command, seen while the mission flies:

- to a pilot mode (POSCTL, ALTCTL, MANUAL, STABILIZED, … — ArduPilot LOITER/POSHOLD/ALT_HOLD read so);
- to an autopilot failsafe mode (RTL, LAND) that our last command does not allow — at any time, also
  while that command is still unconfirmed (an RTL failsafe in the confirmation window is the
  autopilot's, and ABORT must not command HOLD over it);
- once our last command showed in telemetry, to any mode it does not allow (e.g. PX4's HOLD on an
  offboard-loss failsafe).

Only a *change* counts: ArduCopter sits in STABILIZE on the ground before MAVSDK's takeoff switches it to
GUIDED, and a vehicle that was in POSCTL before the mission started was not switched by anyone. A sample
that shows the mode from before our command (a heartbeat built just before it, a delayed link) shows no
change. On the ground (landed) only a pilot or failsafe mode is a takeover: PX4 switches to HOLD as it
disarms after a landing.
"""

from __future__ import annotations

from dataclasses import dataclass

from app.messages import PILOT_MODES, FlightMode

# Modes an autopilot enters on its own when a failsafe triggers (battery, link, geofence, RC loss).
FAILSAFE_MODES = frozenset({FlightMode.RETURN_TO_LAUNCH, FlightMode.LAND})


@dataclass(frozen=True, slots=True)
class Takeover:
    """Someone else switched the mode: ``by`` is "pilot" or "autopilot"."""

    mode: FlightMode
    by: str

    @property
    def reason(self) -> str:
        return f"{self.by} switched to {self.mode.value}"


@dataclass
class ModeWatch:
    """Which flight modes our last command allows, whether telemetry has shown one, and the last mode seen."""

    expected: frozenset[FlightMode] | None = None
    since_s: float = 0.0  # when the command was sent (loop clock)
    confirmed: bool = False
    last_mode: FlightMode | None = None
    last_sample_s: float | None = None

    def expect(self, modes: frozenset[FlightMode], t_s: float) -> None:
        self.expected, self.since_s, self.confirmed = modes, t_s, False

    def clear(self, t_s: float) -> None:
        self.expected, self.since_s, self.confirmed = None, t_s, False

    def observe(self, mode: FlightMode, sample_t_s: float, *, on_ground: bool) -> Takeover | None:
        """Judge one flight-mode sample (``sample_t_s``: when it was received); returns a takeover or ``None``."""
        if self.last_sample_s is not None and sample_t_s < self.last_sample_s:
            return None  # older than one already judged
        previous, self.last_mode, self.last_sample_s = self.last_mode, mode, sample_t_s
        exp = self.expected
        if exp is not None and not self.confirmed and mode in exp and sample_t_s >= self.since_s:
            self.confirmed = True
        if previous is None or mode == previous:
            return None
        if mode in PILOT_MODES:
            return Takeover(mode, "pilot")
        if mode in FAILSAFE_MODES and (exp is None or mode not in exp):
            return Takeover(mode, "autopilot")
        if on_ground:
            return None
        if self.confirmed and exp is not None and mode not in exp:
            return Takeover(mode, "autopilot")
        return None

    def overdue(self, now_s: float, timeout_s: float) -> bool:
        """Our last mode command has not shown in telemetry within ``timeout_s``."""
        return self.expected is not None and not self.confirmed and now_s - self.since_s > timeout_s

    def describe_expected(self) -> str:
        return "/".join(sorted(m.value for m in self.expected)) if self.expected else "-"
