"""The setpoint-loss failsafe of the flight stack, pure: what to do when the setpoint stream stops.

PX4 OFFBOARD falls back to HOLD after COM_OF_LOSS_T seconds without a setpoint ("offboard lost").
ArduCopter GUIDED needs no stream: after GUID_TIMEOUT seconds without a new *velocity* setpoint it
stops and holds, and stays in GUIDED (a position target holds by itself). ``Tuning.offboard_loss_s``
gives the timeout for either profile; the caller switches modes and emits the STATUSTEXT.
"""

from __future__ import annotations

from enum import Enum

from sim.autopilot_modes import Mode
from sim.stack_types import ResolvedSetpoint


class SetpointLoss(Enum):
    """The failsafe's verdict for one tick."""

    NONE = "none"
    OFFBOARD_LOST = "offboard_lost"  # PX4: switch to HOLD
    GUIDED_STOP = "guided_stop"  # ArduCopter: stop and hold, still in GUIDED


def setpoint_loss(
    mode: Mode, guided_sub: str, setpoint: ResolvedSetpoint | None, setpoint_age_s: float, loss_s: float
) -> SetpointLoss:
    """The verdict in ``mode`` (``guided_sub``: ArduCopter GUIDED's sub-mode) for a setpoint ``setpoint_age_s`` old."""
    if mode is Mode.OFFBOARD and setpoint_age_s > loss_s:
        return SetpointLoss.OFFBOARD_LOST
    if mode is Mode.AP_GUIDED and guided_sub == "setpoint" and setpoint is not None:
        if setpoint.is_velocity and setpoint_age_s > loss_s:
            return SetpointLoss.GUIDED_STOP
    return SetpointLoss.NONE
