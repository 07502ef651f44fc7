"""Flight modes of the simulated autopilot and how PX4 and ArduCopter put them on the wire.

One ``Mode`` enum covers both autopilots (ArduCopter modes carry an ``AP_`` prefix); each profile
accepts only its own. Encodings:

- PX4 ``custom_mode`` = ``(main << 16) | (sub << 24)`` (``px4_custom_mode.hpp``); DO_SET_MODE carries
  main in param2 and sub in param3.
- ArduCopter ``custom_mode`` = the mode number; DO_SET_MODE carries it in param2.

``Mode.flight_mode(profile)`` is what MAVSDK 4 reports for it (ArduCopter GUIDED → OFFBOARD,
LOITER/BRAKE → HOLD). Also here: MAV_RESULT values and a flat-earth geodesy helper for home.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from enum import Enum, IntEnum, StrEnum

from app.messages import FlightMode, Vec3


class Profile(StrEnum):
    PX4 = "px4"
    ARDUPILOT = "ardupilot"


class MavResult(IntEnum):
    """MAV_RESULT, as COMMAND_ACK carries it."""

    ACCEPTED = 0
    TEMPORARILY_REJECTED = 1
    DENIED = 2
    UNSUPPORTED = 3
    FAILED = 4
    IN_PROGRESS = 5


class Behaviour(Enum):
    """What a mode makes the vehicle do (a pilot-less sim: pilot modes hold with sticks centred)."""

    HOLD = "hold"
    TAKEOFF = "takeoff"
    LAND = "land"
    RTL = "rtl"
    OFFBOARD = "offboard"


class Mode(Enum):
    """(behaviour, PX4 main/sub or ArduCopter number, MAVSDK FlightMode)."""

    MANUAL = (Behaviour.HOLD, (1, 0), FlightMode.MANUAL)
    ALTCTL = (Behaviour.HOLD, (2, 0), FlightMode.ALTCTL)
    POSCTL = (Behaviour.HOLD, (3, 0), FlightMode.POSCTL)
    AUTO_READY = (Behaviour.HOLD, (4, 1), FlightMode.READY)
    AUTO_TAKEOFF = (Behaviour.TAKEOFF, (4, 2), FlightMode.TAKEOFF)
    AUTO_LOITER = (Behaviour.HOLD, (4, 3), FlightMode.HOLD)
    AUTO_MISSION = (Behaviour.HOLD, (4, 4), FlightMode.MISSION)
    AUTO_RTL = (Behaviour.RTL, (4, 5), FlightMode.RETURN_TO_LAUNCH)
    AUTO_LAND = (Behaviour.LAND, (4, 6), FlightMode.LAND)
    OFFBOARD = (Behaviour.OFFBOARD, (6, 0), FlightMode.OFFBOARD)
    STABILIZED = (Behaviour.HOLD, (7, 0), FlightMode.STABILIZED)
    AP_STABILIZE = (Behaviour.HOLD, 0, FlightMode.STABILIZED)
    AP_ALT_HOLD = (Behaviour.HOLD, 2, FlightMode.ALTCTL)
    AP_AUTO = (Behaviour.HOLD, 3, FlightMode.MISSION)
    AP_GUIDED = (Behaviour.OFFBOARD, 4, FlightMode.OFFBOARD)
    AP_LOITER = (Behaviour.HOLD, 5, FlightMode.HOLD)
    AP_RTL = (Behaviour.RTL, 6, FlightMode.RETURN_TO_LAUNCH)
    AP_LAND = (Behaviour.LAND, 9, FlightMode.LAND)
    AP_POSHOLD = (Behaviour.HOLD, 16, FlightMode.POSCTL)
    AP_BRAKE = (Behaviour.HOLD, 17, FlightMode.HOLD)

    @property
    def behaviour(self) -> Behaviour:
        return self._value_[0]  # not .value: enum's descriptor is slow, and this is read every physics step

    @property
    def profile(self) -> Profile:
        return Profile.ARDUPILOT if self.name.startswith("AP_") else Profile.PX4

    @property
    def flight_mode(self) -> FlightMode:
        """The name MAVSDK 4 reports for this mode."""
        return self._value_[2]

    @property
    def custom_mode(self) -> int:
        """HEARTBEAT ``custom_mode``."""
        if self.profile is Profile.ARDUPILOT:
            return int(self.value[1])
        main, sub = self.value[1]
        return (main << 16) | (sub << 24)

    @property
    def label(self) -> str:
        """The autopilot's own name: ``AUTO.LOITER``, ``POSCTL``, ``GUIDED``…"""
        if self.profile is Profile.ARDUPILOT:
            return self.name[3:]
        return self.name.replace("AUTO_", "AUTO.")


def mode_from_custom(profile: Profile, custom_mode: int) -> Mode | None:
    """Decode a HEARTBEAT/SET_MODE ``custom_mode``."""
    for mode in Mode:
        if mode.profile is profile and mode.custom_mode == custom_mode:
            return mode
    return None


def mode_from_set_mode_params(profile: Profile, param2: float, param3: float) -> Mode | None:
    """Decode MAV_CMD_DO_SET_MODE params (PX4: main, sub; ArduCopter: mode number); NaN → 0."""
    main = 0 if math.isnan(param2) else int(param2)
    sub = 0 if math.isnan(param3) else int(param3)
    if profile is Profile.ARDUPILOT:
        return mode_from_custom(profile, main)
    return mode_from_custom(profile, (main << 16) | (sub << 24))


# What a pilot (or MAVSDK's set_flight_mode) means by a FlightMode, per autopilot.
_BY_FLIGHT_MODE: dict[Profile, dict[FlightMode, Mode]] = {
    Profile.PX4: {
        FlightMode.MANUAL: Mode.MANUAL,
        FlightMode.ALTCTL: Mode.ALTCTL,
        FlightMode.POSCTL: Mode.POSCTL,
        FlightMode.STABILIZED: Mode.STABILIZED,
        FlightMode.HOLD: Mode.AUTO_LOITER,
        FlightMode.TAKEOFF: Mode.AUTO_TAKEOFF,
        FlightMode.MISSION: Mode.AUTO_MISSION,
        FlightMode.RETURN_TO_LAUNCH: Mode.AUTO_RTL,
        FlightMode.LAND: Mode.AUTO_LAND,
        FlightMode.OFFBOARD: Mode.OFFBOARD,
        FlightMode.READY: Mode.AUTO_READY,
    },
    Profile.ARDUPILOT: {
        FlightMode.MANUAL: Mode.AP_STABILIZE,
        FlightMode.STABILIZED: Mode.AP_STABILIZE,
        FlightMode.ALTCTL: Mode.AP_ALT_HOLD,
        FlightMode.POSCTL: Mode.AP_POSHOLD,
        FlightMode.HOLD: Mode.AP_BRAKE,  # what MAVSDK 4.1 sends for hold()/offboard.stop()
        FlightMode.MISSION: Mode.AP_AUTO,
        FlightMode.RETURN_TO_LAUNCH: Mode.AP_RTL,
        FlightMode.LAND: Mode.AP_LAND,
        FlightMode.OFFBOARD: Mode.AP_GUIDED,
    },
}


def mode_for(profile: Profile, flight_mode: FlightMode) -> Mode | None:
    """The autopilot mode MAVSDK (or a pilot) selects for ``flight_mode``; ``None`` if it has none."""
    return _BY_FLIGHT_MODE[profile].get(flight_mode)


def hold_mode(profile: Profile) -> Mode:
    return Mode.AP_BRAKE if profile is Profile.ARDUPILOT else Mode.AUTO_LOITER


def initial_mode(profile: Profile) -> Mode:
    """Boot mode: PX4 SITL shows HOLD; ArduCopter boots in STABILIZE."""
    return Mode.AP_STABILIZE if profile is Profile.ARDUPILOT else Mode.AUTO_LOITER


# -- geodesy (flat earth about home; plenty for a few km) ------------------------------------------

EARTH_RADIUS_M = 6_378_137.0


@dataclass(frozen=True, slots=True)
class GeoPoint:
    """WGS-84 latitude/longitude in degrees, altitude AMSL in metres."""

    lat_deg: float
    lon_deg: float
    alt_m: float

    def offset(self, ned_m: Vec3) -> GeoPoint:
        """The point ``ned_m`` (north, east, down) away from this one."""
        lat_deg = self.lat_deg + math.degrees(ned_m[0] / EARTH_RADIUS_M)
        lon_deg = self.lon_deg + math.degrees(ned_m[1] / (EARTH_RADIUS_M * math.cos(math.radians(self.lat_deg))))
        return GeoPoint(lat_deg, lon_deg, self.alt_m - ned_m[2])

    def ned_to(self, other: GeoPoint) -> Vec3:
        """NED vector (m) from this point to ``other``."""
        north_m = math.radians(other.lat_deg - self.lat_deg) * EARTH_RADIUS_M
        east_m = math.radians(other.lon_deg - self.lon_deg) * EARTH_RADIUS_M * math.cos(math.radians(self.lat_deg))
        return (north_m, east_m, self.alt_m - other.alt_m)


DEFAULT_ORIGIN = GeoPoint(63.62831245, 9.72534, 50.0)
