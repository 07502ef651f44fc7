"""PX4's ``custom_mode`` (HEARTBEAT, CURRENT_MODE) as a ``FlightMode``, the way MAVSDK names it.

``custom_mode`` packs ``main_mode`` in bits 16–23 and ``sub_mode`` in bits 24–31 (``px4_custom_mode.h``);
sub modes only mean something under AUTO.
"""

from __future__ import annotations

from app.messages import FlightMode

MSG_ID_CURRENT_MODE = 436  # MAVLink common CURRENT_MODE (PX4 ≥ 1.15 streams it)
MAV_CMD_SET_MESSAGE_INTERVAL = 511

_MAIN = {
    1: FlightMode.MANUAL,
    2: FlightMode.ALTCTL,
    3: FlightMode.POSCTL,
    5: FlightMode.ACRO,
    6: FlightMode.OFFBOARD,
    7: FlightMode.STABILIZED,
    8: FlightMode.RATTITUDE,
}
_AUTO = {
    1: FlightMode.READY,
    2: FlightMode.TAKEOFF,
    3: FlightMode.HOLD,  # AUTO.LOITER
    4: FlightMode.MISSION,
    5: FlightMode.RETURN_TO_LAUNCH,
    6: FlightMode.LAND,
    8: FlightMode.FOLLOW_ME,  # AUTO.FOLLOW_TARGET
    9: FlightMode.LAND,  # AUTO.PRECLAND
}
AUTO_MAIN_MODE = 4


def px4_flight_mode(custom_mode: int) -> FlightMode:
    main, sub = (custom_mode >> 16) & 0xFF, (custom_mode >> 24) & 0xFF
    if main == AUTO_MAIN_MODE:
        return _AUTO.get(sub, FlightMode.UNKNOWN)
    return _MAIN.get(main, FlightMode.UNKNOWN)
