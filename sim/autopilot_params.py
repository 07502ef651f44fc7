"""Parameters of the simulated autopilot and their PARAM_VALUE encoding.

PX4 sends integer parameters *bytewise* in the float field (the int's four bytes reinterpreted as a
float); ArduPilot sends them as a plain cast. REAL32 values travel as themselves. Units follow the
autopilot's own parameter (PX4: metres, seconds; ArduCopter: centimetres, cm/s, seconds), and the
flight stack reads them through the ``Tuning`` accessors below, which return SI units.
"""

from __future__ import annotations

import math
import struct
from dataclasses import dataclass
from enum import IntEnum

from sim.autopilot_modes import Profile


class ParamType(IntEnum):
    """MAV_PARAM_TYPE."""

    INT8 = 2
    INT16 = 4
    INT32 = 6
    REAL32 = 9


@dataclass(slots=True)
class Param:
    name: str
    value: float
    type: ParamType


_PX4_DEFAULTS: tuple[tuple[str, float, ParamType], ...] = (
    ("MIS_TAKEOFF_ALT", 2.5, ParamType.REAL32),  # m above home
    ("COM_OF_LOSS_T", 1.0, ParamType.REAL32),  # s without offboard setpoints → failsafe
    ("COM_DISARM_LAND", 2.0, ParamType.REAL32),  # s on the ground after landing → disarm
    ("COM_DISARM_PRFLT", 10.0, ParamType.REAL32),  # s armed without takeoff → disarm
    ("RTL_RETURN_ALT", 10.0, ParamType.REAL32),  # m above home
    ("MPC_XY_CRUISE", 5.0, ParamType.REAL32),  # m/s
    ("MPC_TKO_SPEED", 1.5, ParamType.REAL32),  # m/s
    ("MPC_LAND_SPEED", 0.7, ParamType.REAL32),  # m/s
    ("MPC_Z_VEL_MAX_DN", 1.5, ParamType.REAL32),  # m/s
    ("COM_OBL_RC_ACT", 0, ParamType.INT32),
    ("MAV_SYS_ID", 1, ParamType.INT32),
    ("SYS_AUTOSTART", 10015, ParamType.INT32),  # SITL quadcopter airframe
)

_ARDUPILOT_DEFAULTS: tuple[tuple[str, float, ParamType], ...] = (
    ("RTL_ALT", 1500, ParamType.INT32),  # cm above home
    ("WPNAV_SPEED", 500, ParamType.REAL32),  # cm/s
    ("WPNAV_SPEED_UP", 250, ParamType.REAL32),  # cm/s (takeoff climb)
    ("LAND_SPEED", 50, ParamType.INT16),  # cm/s (final descent)
    ("LAND_SPEED_HIGH", 0, ParamType.INT16),  # cm/s, 0 = WPNAV_SPEED_DN
    ("WPNAV_SPEED_DN", 150, ParamType.REAL32),  # cm/s
    ("GUID_TIMEOUT", 3.0, ParamType.REAL32),  # s without a guided setpoint → stop
    ("DISARM_DELAY", 10, ParamType.INT8),  # s landed → disarm
    ("SYSID_THISMAV", 1, ParamType.INT16),
    ("FRAME_CLASS", 1, ParamType.INT8),  # quad
    ("PSC_JERK_XY", 5.0, ParamType.REAL32),  # m/s³, GUIDED's horizontal input shaping (range 1-20)
    ("WPNAV_ACCEL", 250.0, ParamType.REAL32),  # cm/s², GUIDED's horizontal acceleration limit
    ("PSC_JERK_Z", 5.0, ParamType.REAL32),  # m/s³, GUIDED's vertical input shaping (range 5-50)
    ("WPNAV_ACCEL_Z", 100.0, ParamType.REAL32),  # cm/s², GUIDED's vertical acceleration limit (range 50-500)
)


class ParamStore:
    """Named parameters with stable indices (the order above), as PARAM_REQUEST_LIST sends them."""

    def __init__(self, profile: Profile, overrides: dict[str, float] | None = None) -> None:
        self.profile = profile
        defaults = _ARDUPILOT_DEFAULTS if profile is Profile.ARDUPILOT else _PX4_DEFAULTS
        self._params = [Param(n, float(v), t) for n, v, t in defaults]
        self._index = {p.name: i for i, p in enumerate(self._params)}
        self.version = 0  # counts the sets: a reader caching a value knows when to read it again
        for name, value in (overrides or {}).items():
            if not self.set(name, value):
                raise KeyError(f"unknown parameter {name!r} for {profile}")

    def __len__(self) -> int:
        return len(self._params)

    def __contains__(self, name: object) -> bool:
        return name in self._index

    def get(self, name: str) -> float:
        return self._params[self._index[name]].value

    def param(self, name: str) -> Param | None:
        i = self._index.get(name)
        return None if i is None else self._params[i]

    def index_of(self, name: str) -> int:
        return self._index[name]

    def by_index(self, index: int) -> Param | None:
        return self._params[index] if 0 <= index < len(self._params) else None

    def all(self) -> list[Param]:
        return list(self._params)

    def set(self, name: str, value: float) -> bool:
        """Set a parameter (ints are rounded); False if unknown or not finite."""
        p = self.param(name)
        if p is None or not math.isfinite(value):
            return False
        p.value = (
            float(round(value))
            if p.type is not ParamType.REAL32
            else float(struct.unpack("<f", struct.pack("<f", value))[0])
        )
        self.version += 1
        return True

    # -- wire encoding -------------------------------------------------------------------------

    def encode(self, p: Param) -> float:
        """The float PARAM_VALUE carries for ``p``."""
        if p.type is ParamType.REAL32:
            return p.value
        if self.profile is Profile.PX4:
            fmt = {ParamType.INT8: "<b3x", ParamType.INT16: "<h2x", ParamType.INT32: "<i"}[p.type]
            return float(struct.unpack("<f", struct.pack(fmt, int(p.value)))[0])
        return float(int(p.value))

    def decode(self, wire_value: float, wire_type: int) -> float:
        """The value a PARAM_SET means, given the type the sender says it used."""
        if wire_type == ParamType.REAL32 or self.profile is Profile.ARDUPILOT:
            return wire_value
        fmt = {ParamType.INT8: "<b3x", ParamType.INT16: "<h2x"}.get(wire_type, "<i")  # type: ignore[call-overload]
        return float(struct.unpack(fmt, struct.pack("<f", wire_value))[0])


class Tuning:
    """The flight stack's view of the parameters, in SI units, whatever the profile."""

    def __init__(self, params: ParamStore) -> None:
        self._p = params
        self._ap = params.profile is Profile.ARDUPILOT

    def takeoff_alt_m(self) -> float:
        return 2.5 if self._ap else self._p.get("MIS_TAKEOFF_ALT")

    def shaping(self) -> tuple[float, float, float, float] | None:
        """ArduCopter GUIDED's shaping limits: (jerk m/s³, acceleration m/s²) horizontally, then vertically; None on
        PX4. Values outside the documented ranges (PSC_JERK_XY 1-20 m/s³, WPNAV_ACCEL 50-500 cm/s², PSC_JERK_Z
        5-50 m/s³, WPNAV_ACCEL_Z 50-500 cm/s²) are taken at the nearest end (a zero would stop the shaping)."""
        if not self._ap:
            return None
        get = self._p.get
        return (
            min(max(get("PSC_JERK_XY"), 1.0), 20.0),
            min(max(get("WPNAV_ACCEL"), 50.0), 500.0) / 100.0,
            min(max(get("PSC_JERK_Z"), 5.0), 50.0),
            min(max(get("WPNAV_ACCEL_Z"), 50.0), 500.0) / 100.0,
        )

    def offboard_loss_s(self) -> float:
        return self._p.get("GUID_TIMEOUT") if self._ap else self._p.get("COM_OF_LOSS_T")

    def disarm_land_s(self) -> float:
        return self._p.get("DISARM_DELAY") if self._ap else self._p.get("COM_DISARM_LAND")

    def disarm_preflight_s(self) -> float:
        return self._p.get("DISARM_DELAY") if self._ap else self._p.get("COM_DISARM_PRFLT")

    def rtl_alt_m(self) -> float:
        return self._p.get("RTL_ALT") / 100.0 if self._ap else self._p.get("RTL_RETURN_ALT")

    def cruise_mps(self) -> float:
        return self._p.get("WPNAV_SPEED") / 100.0 if self._ap else self._p.get("MPC_XY_CRUISE")

    def takeoff_speed_mps(self) -> float:
        return self._p.get("WPNAV_SPEED_UP") / 100.0 if self._ap else self._p.get("MPC_TKO_SPEED")

    def land_speed_mps(self, height_m: float) -> float:
        """Descent speed at ``height_m`` above ground: fast high up, slow for the touchdown."""
        if self._ap:
            slow = self._p.get("LAND_SPEED") / 100.0
            fast = (self._p.get("LAND_SPEED_HIGH") or self._p.get("WPNAV_SPEED_DN")) / 100.0
            return fast if height_m > 10.0 else slow  # LAND_ALT_LOW 10 m
        slow, fast = self._p.get("MPC_LAND_SPEED"), self._p.get("MPC_Z_VEL_MAX_DN")
        # PX4: MPC_LAND_ALT1 10 m (fast above), MPC_LAND_ALT2 5 m (slow below), linear in between.
        if height_m >= 10.0:
            return fast
        if height_m <= 5.0:
            return slow
        return slow + (fast - slow) * (height_m - 5.0) / 5.0
