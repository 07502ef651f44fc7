"""MAVLink telemetry messages built from the flight stack, as PX4 / ArduCopter put them on the wire.

Units on the wire are MAVLink's (degE7, mm, cm/s, cdeg, mV, cA); this module converts from the stack's
SI/NED truth. Messages are built without a link; each link packs them with its own sequence numbers.
Which messages exist, and at what rate PX4 SITL streams them unasked, is ``DEFAULT_RATES_HZ``.
"""

from __future__ import annotations

import math
import time

from pymavlink.dialects.v20 import common as mavlink
from pymavlink.dialects.v20 import development as mavlink_dev
from pymavlink.dialects.v20.common import MAVLink_message as Message

from app.estimators.rotations import quat_from_euler_zyx
from app.messages import LandedState
from sim.autopilot_modes import Mode, Profile
from sim.autopilot_params import Param
from sim.flight_stack import FlightStack

MSG = mavlink

SENSORS = (
    MSG.MAV_SYS_STATUS_SENSOR_3D_GYRO
    | MSG.MAV_SYS_STATUS_SENSOR_3D_ACCEL
    | MSG.MAV_SYS_STATUS_SENSOR_3D_MAG
    | MSG.MAV_SYS_STATUS_SENSOR_ABSOLUTE_PRESSURE
    | MSG.MAV_SYS_STATUS_SENSOR_GPS
    | MSG.MAV_SYS_STATUS_AHRS
    | MSG.MAV_SYS_STATUS_SENSOR_BATTERY
    | MSG.MAV_SYS_STATUS_PREARM_CHECK
)

# PX4 SITL streams all of these unasked; ArduPilot streams nothing but HEARTBEAT until asked.
DEFAULT_RATES_HZ: dict[int, float] = {
    MSG.MAVLINK_MSG_ID_SYS_STATUS: 1.0,
    MSG.MAVLINK_MSG_ID_EXTENDED_SYS_STATE: 5.0,
    MSG.MAVLINK_MSG_ID_LOCAL_POSITION_NED: 30.0,
    MSG.MAVLINK_MSG_ID_GLOBAL_POSITION_INT: 10.0,
    MSG.MAVLINK_MSG_ID_ATTITUDE: 30.0,
    MSG.MAVLINK_MSG_ID_ATTITUDE_QUATERNION: 10.0,
    MSG.MAVLINK_MSG_ID_GPS_RAW_INT: 5.0,
    MSG.MAVLINK_MSG_ID_BATTERY_STATUS: 1.0,
    MSG.MAVLINK_MSG_ID_HOME_POSITION: 0.5,
    MSG.MAVLINK_MSG_ID_VFR_HUD: 4.0,
    MSG.MAVLINK_MSG_ID_SYSTEM_TIME: 0.0,  # known (can be requested) but off by default
    mavlink_dev.MAVLINK_MSG_ID_CURRENT_MODE: 0.0,  # PX4 ≥ 1.15; off here until asked for
}
STREAMABLE = frozenset(DEFAULT_RATES_HZ)
PX4_ONLY = frozenset({mavlink_dev.MAVLINK_MSG_ID_CURRENT_MODE})  # ArduPilot refuses these
# PX4 sends CURRENT_MODE (at most at its stream rate) when vehicle_status was published since the last one:
# on every mode change, and at least every 0.5 s (commander's slowest publication).
CURRENT_MODE_REFRESH_S = 0.5
# MAV_STANDARD_MODE of PX4's modes (mode_util::getStandardModeFromNavState); others are 0 (non-standard).
_STANDARD_MODES = {
    Mode.POSCTL: 1,  # POSITION_HOLD
    Mode.ALTCTL: 4,  # ALTITUDE_HOLD
    Mode.AUTO_RTL: 5,  # SAFE_RECOVERY
    Mode.AUTO_MISSION: 6,
    Mode.AUTO_LAND: 7,
    Mode.AUTO_TAKEOFF: 8,
}
MAX_RATE_HZ = 50.0

_LANDED = {
    LandedState.UNKNOWN: MSG.MAV_LANDED_STATE_UNDEFINED,
    LandedState.ON_GROUND: MSG.MAV_LANDED_STATE_ON_GROUND,
    LandedState.IN_AIR: MSG.MAV_LANDED_STATE_IN_AIR,
    LandedState.TAKING_OFF: MSG.MAV_LANDED_STATE_TAKEOFF,
    LandedState.LANDING: MSG.MAV_LANDED_STATE_LANDING,
}


def _base_mode(mode: Mode, armed: bool) -> int:
    """HEARTBEAT base_mode: CUSTOM_MODE_ENABLED always, SAFETY_ARMED, and the flags PX4/ArduCopter add."""
    base = MSG.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED | (MSG.MAV_MODE_FLAG_SAFETY_ARMED if armed else 0)
    stab, guided = MSG.MAV_MODE_FLAG_STABILIZE_ENABLED, MSG.MAV_MODE_FLAG_GUIDED_ENABLED
    manual, auto = MSG.MAV_MODE_FLAG_MANUAL_INPUT_ENABLED, MSG.MAV_MODE_FLAG_AUTO_ENABLED
    if mode.profile is Profile.ARDUPILOT:
        return base | manual | stab | (guided if mode not in (Mode.AP_STABILIZE, Mode.AP_ALT_HOLD) else 0)
    if mode is Mode.MANUAL:
        return base | manual
    if mode in (Mode.STABILIZED, Mode.ALTCTL):
        return base | manual | stab
    if mode is Mode.POSCTL:
        return base | manual | stab | guided
    return base | auto | stab | guided


def _cdeg(angle_rad: float) -> int:
    return round(math.degrees(angle_rad) * 100.0) % 36000


class TelemetryEncoder:
    """Builds the messages; ``message(msg_id)`` for streams and REQUEST_MESSAGE."""

    def __init__(self, stack: FlightStack) -> None:
        self.stack = stack
        self._mav = mavlink.MAVLink(None, srcSystem=1, srcComponent=1)
        self._ap = stack.profile is Profile.ARDUPILOT
        self._current_mode_sent: tuple[int, float] | None = None  # (custom_mode, t_s) of the last CURRENT_MODE

    def _ms(self) -> int:
        return int(self.stack.time_since_boot_s * 1000.0) & 0xFFFFFFFF

    def _us(self) -> int:
        return int(self.stack.time_since_boot_s * 1e6)

    def heartbeat(self) -> Message:
        st = self.stack
        autopilot = MSG.MAV_AUTOPILOT_ARDUPILOTMEGA if self._ap else MSG.MAV_AUTOPILOT_PX4
        status = MSG.MAV_STATE_ACTIVE if st.armed else MSG.MAV_STATE_STANDBY
        return self._mav.heartbeat_encode(
            MSG.MAV_TYPE_QUADROTOR, autopilot, _base_mode(st.mode, st.armed), st.mode.custom_mode, status, 3
        )

    def streamable(self, msg_id: int) -> bool:
        return msg_id in STREAMABLE and not (self._ap and msg_id in PX4_ONLY)

    def stream(self, msg_id: int, t_s: float) -> Message | None:
        """The message a stream sends at ``t_s``; None when there is nothing to send (CURRENT_MODE unchanged)."""
        if msg_id == mavlink_dev.MAVLINK_MSG_ID_CURRENT_MODE:
            custom, last = self.stack.mode.custom_mode, self._current_mode_sent
            if last is not None and last[0] == custom and t_s - last[1] < CURRENT_MODE_REFRESH_S:
                return None
            self._current_mode_sent = (custom, t_s)
        return self.message(msg_id)

    def current_mode(self) -> Message | None:
        """CURRENT_MODE (PX4 only): the mode as in HEARTBEAT, and the standard mode it maps to."""
        if self._ap:
            return None
        mode = self.stack.mode
        return mavlink_dev.MAVLink_current_mode_message(
            _STANDARD_MODES.get(mode, 0), mode.custom_mode, mode.custom_mode
        )

    def message(self, msg_id: int) -> Message | None:
        build = {
            MSG.MAVLINK_MSG_ID_SYS_STATUS: self.sys_status,
            MSG.MAVLINK_MSG_ID_EXTENDED_SYS_STATE: self.extended_sys_state,
            MSG.MAVLINK_MSG_ID_LOCAL_POSITION_NED: self.local_position_ned,
            MSG.MAVLINK_MSG_ID_GLOBAL_POSITION_INT: self.global_position_int,
            MSG.MAVLINK_MSG_ID_ATTITUDE: self.attitude,
            MSG.MAVLINK_MSG_ID_ATTITUDE_QUATERNION: self.attitude_quaternion,
            MSG.MAVLINK_MSG_ID_GPS_RAW_INT: self.gps_raw_int,
            MSG.MAVLINK_MSG_ID_BATTERY_STATUS: self.battery_status,
            MSG.MAVLINK_MSG_ID_HOME_POSITION: self.home_position,
            MSG.MAVLINK_MSG_ID_VFR_HUD: self.vfr_hud,
            MSG.MAVLINK_MSG_ID_SYSTEM_TIME: self.system_time,
            MSG.MAVLINK_MSG_ID_AUTOPILOT_VERSION: self.autopilot_version,
            MSG.MAVLINK_MSG_ID_HEARTBEAT: self.heartbeat,
            mavlink_dev.MAVLINK_MSG_ID_CURRENT_MODE: self.current_mode,
        }.get(msg_id)
        return build() if build is not None else None

    def sys_status(self) -> Message:
        st = self.stack
        health = SENSORS
        if not st.gps_ok:
            health &= ~(MSG.MAV_SYS_STATUS_SENSOR_GPS | MSG.MAV_SYS_STATUS_AHRS)
        if not st.prearm_ok:
            health &= ~MSG.MAV_SYS_STATUS_PREARM_CHECK
        b = st.dyn.battery
        return self._mav.sys_status_encode(
            SENSORS,
            SENSORS,
            health,
            250,
            int(b.voltage_v * 1000),
            int(b.current_a * 100),
            int(b.remaining_frac * 100),
            0,
            0,
            0,
            0,
            0,
            0,
        )

    def extended_sys_state(self) -> Message:
        return self._mav.extended_sys_state_encode(MSG.MAV_VTOL_STATE_UNDEFINED, _LANDED[self.stack.landed_state])

    def local_position_ned(self) -> Message:
        s = self.stack.estimate()
        p, v = s.pos_ned_m, s.vel_ned_mps
        return self._mav.local_position_ned_encode(self._ms(), p[0], p[1], p[2], v[0], v[1], v[2])

    def global_position_int(self) -> Message:
        st = self.stack
        s = st.estimate()
        geo = st.origin.offset(s.pos_ned_m)
        home_down_m = st.home_ned_m[2] if st.home_ned_m else 0.0
        v = s.vel_ned_mps
        return self._mav.global_position_int_encode(
            self._ms(),
            int(geo.lat_deg * 1e7),
            int(geo.lon_deg * 1e7),
            int(geo.alt_m * 1000),
            int((home_down_m - s.pos_ned_m[2]) * 1000),
            int(v[0] * 100),
            int(v[1] * 100),
            int(v[2] * 100),
            _cdeg(s.yaw_rad),
        )

    def attitude(self) -> Message:
        s = self.stack.estimate()  # the reported attitude, with the estimator's tilt error
        r = s.rates_radps
        return self._mav.attitude_encode(self._ms(), s.roll_rad, s.pitch_rad, s.yaw_rad, r[0], r[1], r[2])

    def attitude_quaternion(self) -> Message:
        s = self.stack.estimate()  # the reported attitude, with the estimator's tilt error
        q, r = quat_from_euler_zyx(s.roll_rad, s.pitch_rad, s.yaw_rad), s.rates_radps
        return self._mav.attitude_quaternion_encode(self._ms(), *q, r[0], r[1], r[2])

    def gps_raw_int(self) -> Message:
        st = self.stack
        s = st.estimate()
        geo = st.origin.offset(s.pos_ned_m)
        fix = 3 if st.gps_ok else 1
        v = s.vel_ned_mps
        speed_mps = math.hypot(v[0], v[1])
        cog = _cdeg(math.atan2(v[1], v[0])) if speed_mps > 0.2 else 65535
        return self._mav.gps_raw_int_encode(
            self._us(),
            fix,
            int(geo.lat_deg * 1e7),
            int(geo.lon_deg * 1e7),
            int(geo.alt_m * 1000),
            80,
            120,
            int(speed_mps * 100),
            cog,
            14 if st.gps_ok else 0,
            int(geo.alt_m * 1000),
            500,
            800,
            200,
            0,
            0,
        )

    def battery_status(self) -> Message:
        b = self.stack.dyn.battery
        cells = b.params.cells
        cell_mv = int(b.voltage_v * 1000 / cells)
        voltages = [cell_mv] * cells + [65535] * (10 - cells)
        remaining = b.remaining_frac
        charge_state = 1 if remaining > 0.3 else 2 if remaining > 0.15 else 3
        time_left_s = int(remaining * b.params.capacity_mah * 3.6 / max(b.current_a, 0.1))
        return self._mav.battery_status_encode(
            0,
            MSG.MAV_BATTERY_FUNCTION_ALL,
            MSG.MAV_BATTERY_TYPE_LIPO,
            32767,
            voltages,
            int(b.current_a * 100),
            int(b.consumed_mah),
            -1,
            int(remaining * 100),
            time_left_s,
            charge_state,
        )

    def home_position(self) -> Message | None:
        st = self.stack
        home, geo = st.home_ned_m, st.home_geo
        if home is None or geo is None:
            return None
        if st.profile is Profile.ARDUPILOT:
            home = (0.0, 0.0, 0.0)  # ArduCopter leaves x, y, z at 0 (its local origin is the EKF origin)
        return self._mav.home_position_encode(
            int(geo.lat_deg * 1e7),
            int(geo.lon_deg * 1e7),
            int(geo.alt_m * 1000),
            home[0],
            home[1],
            home[2],
            [1.0, 0.0, 0.0, 0.0],
            0.0,
            0.0,
            0.0,
            self._us(),
        )

    def vfr_hud(self) -> Message:
        st = self.stack
        s = st.estimate()
        v, w = s.vel_ned_mps, s.wind_ned_mps
        air_mps = math.hypot(v[0] - w[0], v[1] - w[1])
        throttle = int(min(100.0, 50.0 * s.thrust_mps2 / 9.80665))
        alt_m = st.origin.offset(s.pos_ned_m).alt_m
        return self._mav.vfr_hud_encode(
            air_mps, math.hypot(v[0], v[1]), _cdeg(s.yaw_rad) // 100, throttle, alt_m, -v[2]
        )

    def system_time(self) -> Message:
        return self._mav.system_time_encode(int(time.time() * 1e6), self._ms())

    def autopilot_version(self) -> Message:
        caps = (
            MSG.MAV_PROTOCOL_CAPABILITY_MISSION_FLOAT
            | MSG.MAV_PROTOCOL_CAPABILITY_PARAM_FLOAT
            | MSG.MAV_PROTOCOL_CAPABILITY_MISSION_INT
            | MSG.MAV_PROTOCOL_CAPABILITY_COMMAND_INT
            | MSG.MAV_PROTOCOL_CAPABILITY_SET_POSITION_TARGET_LOCAL_NED
            | MSG.MAV_PROTOCOL_CAPABILITY_SET_POSITION_TARGET_GLOBAL_INT
            | MSG.MAV_PROTOCOL_CAPABILITY_MAVLINK2
            | (
                MSG.MAV_PROTOCOL_CAPABILITY_PARAM_ENCODE_C_CAST
                if self._ap
                else MSG.MAV_PROTOCOL_CAPABILITY_PARAM_ENCODE_BYTEWISE
            )
        )
        major, minor, patch = (4, 5, 7) if self._ap else (1, 15, 0)
        version = (major << 24) | (minor << 16) | (patch << 8) | 255  # FIRMWARE_VERSION_TYPE_OFFICIAL
        return self._mav.autopilot_version_encode(
            caps, version, 0, 0, 0, [0] * 8, [0] * 8, [0] * 8, 0x26AC, 0x11, 0x5EA91C0000000001
        )

    def statustext(self, text: str, severity: int) -> Message:
        return self._mav.statustext_encode(severity, text[:50].encode())

    def param_value(self, p: Param) -> Message:
        store = self.stack.params
        return self._mav.param_value_encode(
            p.name.encode(), store.encode(p), int(p.type), len(store), store.index_of(p.name)
        )

    def command_ack(self, command: int, result: int, target_system: int, target_component: int) -> Message:
        return self._mav.command_ack_encode(command, result, 0, 0, target_system, target_component)

    def message_interval(self, msg_id: int, interval_us: int) -> Message:
        return self._mav.message_interval_encode(msg_id, interval_us)

    def ping_reply(self, ping: Message) -> Message:
        """PING answered to its sender (same time_usec and seq)."""
        return self._mav.ping_encode(ping.time_usec, ping.seq, ping.get_srcSystem(), ping.get_srcComponent())

    def timesync_reply(self, now_ns: int, ts1: int) -> Message:
        """TIMESYNC reply: tc1 = our time (ns since boot, never 0: that would be a request), ts1 echoed."""
        return self._mav.timesync_encode(max(1, now_ns), ts1)
