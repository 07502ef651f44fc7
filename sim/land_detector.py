"""The flight stack on the ground: land detection, motor spool-up and auto-disarm, pure and time-injected.

Like PX4's land detector and commander's auto-disarm [ArduCopter's in brackets]. Times are seconds on
the caller's clock.

- ``LandDetector.update`` runs once per physics substep, after the dynamics moved: it turns ground
  contact into the MAVLink landed state — leaving the ground is a takeoff at once; touching it is a
  landing only after ``LAND_DETECT_S`` of contact — and keeps the two facts auto-disarm needs: since
  when the vehicle has been on the ground and whether it flew since it was armed;
- ``LandDetector.auto_disarm`` says whether to disarm: COM_DISARM_PRFLT after arming without a
  takeoff, COM_DISARM_LAND after a landing [DISARM_DELAY for both; LAND/RTL disarm at touchdown];
- ``Spoolup`` keeps the motors of an armed vehicle on the ground idle until a climb has been wanted
  for ``SPOOLUP_S``.

They only keep their own timers: the caller emits the events and disarms.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

from app.messages import LandedState
from sim.autopilot_params import Tuning

LAND_DETECT_S = 0.5  # on the ground this long while armed → landed
SPOOLUP_S = 0.5  # motors spool up this long before a takeoff leaves the ground


@dataclass(frozen=True, slots=True)
class LandedUpdate:
    """The landed state after an update; ``detected`` names a takeoff or landing detected just now."""

    landed_state: LandedState
    detected: Literal["takeoff", "landing"] | None = None


_NOTHING_DETECTED = {s: LandedUpdate(s) for s in LandedState}  # the answer of almost every update, built once


@dataclass(frozen=True, slots=True)
class AutoDisarm:
    """A decision to disarm: the STATUSTEXT to send and the reason the ``armed`` event carries."""

    text: str
    reason: str


class LandDetector:
    """Ground contact → landed state, and the on-ground timers behind auto-disarm."""

    def __init__(self) -> None:
        self.contact_since_s: float | None = None  # touching the ground while still "in air" since
        self.ground_since_s = 0.0  # landed (or armed on the ground) since
        self.flew_since_arm = False

    def on_arm(self, t_s: float) -> None:
        """The vehicle was armed (on the ground) at ``t_s``: the preflight auto-disarm timer starts."""
        self.ground_since_s = t_s
        self.flew_since_arm = False

    def update(
        self, t_s: float, landed_state: LandedState, on_ground: bool, taking_off: bool, landing_phase: bool
    ) -> LandedUpdate:
        """The landed state at ``t_s``, given ground contact and whether a takeoff or landing is flown."""
        if landed_state is LandedState.ON_GROUND:
            if on_ground:
                return _NOTHING_DETECTED[landed_state]
            self.flew_since_arm = True
            self.contact_since_s = None
            detected: Literal["takeoff"] | None = "takeoff"
        elif on_ground:
            if self.contact_since_s is None:
                self.contact_since_s = t_s
            if t_s - self.contact_since_s >= LAND_DETECT_S:
                self.ground_since_s = t_s
                return LandedUpdate(LandedState.ON_GROUND, "landing")
            return _NOTHING_DETECTED[landed_state]
        else:
            self.contact_since_s = None
            detected = None
        state = LandedState.TAKING_OFF if taking_off else LandedState.LANDING if landing_phase else LandedState.IN_AIR
        return _NOTHING_DETECTED[state] if detected is None else LandedUpdate(state, detected)

    def auto_disarm(
        self, t_s: float, landed_state: LandedState, disarm_at_touchdown: bool, tuning: Tuning
    ) -> AutoDisarm | None:
        """Whether an armed vehicle disarms at ``t_s``; ``disarm_at_touchdown``: ArduCopter landing in LAND/RTL."""
        if landed_state is not LandedState.ON_GROUND:
            return None
        on_ground_s = t_s - self.ground_since_s
        if disarm_at_touchdown and self.flew_since_arm:
            return AutoDisarm("Disarming: landed", "auto_disarm_land")
        limit_s = tuning.disarm_land_s() if self.flew_since_arm else tuning.disarm_preflight_s()
        if limit_s > 0.0 and on_ground_s >= limit_s:
            kind = "land" if self.flew_since_arm else "preflight"
            return AutoDisarm(f"Disarmed by auto {kind} disarming", f"auto_disarm_{kind}")
        return None


class Spoolup:
    """Motors on the ground: they spin up only once a climb has been wanted for ``SPOOLUP_S``."""

    def __init__(self) -> None:
        self.since_s: float | None = None  # a climb wanted on the ground since

    def motors_on(self, t_s: float, armed: bool, landed: bool, climb_wanted: bool) -> bool:
        """Thrust only when ``armed``; when ``landed``, only after ``climb_wanted`` held for SPOOLUP_S."""
        if not armed or not landed:
            self.since_s = None
            return armed
        if not climb_wanted:
            self.since_s = None  # idle on the ground
            return False
        if self.since_s is None:
            self.since_s = t_s
        return t_s - self.since_s >= SPOOLUP_S
