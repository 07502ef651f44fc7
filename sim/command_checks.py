"""Why the flight stack refuses to arm or to switch mode: its pre-arm and mode-requirement checks, pure.

Each check returns the STATUSTEXT the autopilot sends when it refuses (PX4 wording), or ``None`` when
the command may go ahead; the caller answers DENIED and emits the text.

- arming needs pre-arm OK (GPS fix, home set, no injected failure), the vehicle on the ground and an
  armable mode: not LAND/RTL [nor BRAKE or AUTO];
- a mode switch needs a position estimate unless the mode is flown by a pilot without one (MANUAL,
  STABILIZED, ALTCTL [STABILIZE, ALT_HOLD]); OFFBOARD needs a setpoint in the last
  ``OFFBOARD_AVAILABLE_S``; MISSION [AUTO] needs a mission, and the sim never has one.
"""

from __future__ import annotations

from app.messages import LandedState
from sim.autopilot_modes import Mode

OFFBOARD_AVAILABLE_S = 0.5  # a setpoint this recent makes OFFBOARD available
NOT_ARMABLE = (Mode.AUTO_LAND, Mode.AUTO_RTL, Mode.AP_LAND, Mode.AP_RTL, Mode.AP_BRAKE, Mode.AP_AUTO)
PILOTLESS_OK = {Mode.MANUAL, Mode.STABILIZED, Mode.ALTCTL, Mode.AP_STABILIZE, Mode.AP_ALT_HOLD}


def arming_denial(
    prearm_ok: bool, prearm_failure: str | None, gps_ok: bool, landed_state: LandedState, mode: Mode
) -> str | None:
    """Why arming in ``mode`` is refused (``prearm_failure``: an injected pre-arm failure), or ``None``."""
    if not prearm_ok:
        reason = prearm_failure or ("no GPS fix" if not gps_ok else "no home")
        return f"Arming denied: {reason}"
    if landed_state is not LandedState.ON_GROUND:
        return "Arming denied: not landed"
    if mode in NOT_ARMABLE:
        return f"Arming denied: {mode.label} mode not armable"
    return None


def mode_switch_denial(mode: Mode, gps_ok: bool, setpoint_age_s: float) -> str | None:
    """Why switching to ``mode`` is refused (``setpoint_age_s``: the last offboard setpoint's age), or ``None``."""
    if not gps_ok and mode not in PILOTLESS_OK:
        return f"{mode.label} denied: no position estimate"
    if mode is Mode.OFFBOARD and setpoint_age_s > OFFBOARD_AVAILABLE_S:
        return "Switching to Offboard is currently not available"
    if mode in (Mode.AUTO_MISSION, Mode.AP_AUTO):
        return "Mission rejected: no mission loaded"
    return None
