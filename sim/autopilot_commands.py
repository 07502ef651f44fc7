"""COMMAND_LONG / COMMAND_INT handling of the simulated autopilot: MAV_CMD → flight stack → MAV_RESULT.

Param conventions as on the wire: PX4 leaves unset params NaN (ArduPilot 0.0); PX4's NAV_TAKEOFF
param7 is an AMSL altitude, ArduCopter's is metres above home; DO_SET_MODE carries the base mode in
param1 (only its CUSTOM_MODE_ENABLED bit matters) and PX4 main/sub or the ArduCopter mode number in
param2/param3. Commands that have to send something besides the ACK (REQUEST_MESSAGE, …) return it
in ``Reply.extra``; the endpoint sends the ACK first.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field

from pymavlink.dialects.v20 import common as mavlink

from sim.autopilot_modes import GeoPoint, MavResult, Mode, Profile, mode_from_set_mode_params
from sim.autopilot_params import Param
from sim.autopilot_telemetry import MAX_RATE_HZ, Message, TelemetryEncoder
from sim.flight_stack import FlightStack

MSG = mavlink
FORCE_DISARM_MAGIC = 21196

# Modes a pilot may select from the pilot/GCS port (OFFBOARD still needs streaming setpoints).
PILOT_MODES = frozenset(
    {
        Mode.MANUAL,
        Mode.ALTCTL,
        Mode.POSCTL,
        Mode.STABILIZED,
        Mode.AUTO_LOITER,
        Mode.AUTO_RTL,
        Mode.AUTO_LAND,
        Mode.OFFBOARD,
        Mode.AP_STABILIZE,
        Mode.AP_ALT_HOLD,
        Mode.AP_POSHOLD,
        Mode.AP_LOITER,
        Mode.AP_BRAKE,
        Mode.AP_RTL,
        Mode.AP_LAND,
        Mode.AP_GUIDED,
    }
)


# REQUEST_DATA_STREAM (ArduPilot's way of asking) → the messages each stream group carries.
DATA_STREAMS: dict[int, tuple[int, ...]] = {
    2: (MSG.MAVLINK_MSG_ID_SYS_STATUS, MSG.MAVLINK_MSG_ID_GPS_RAW_INT),
    6: (MSG.MAVLINK_MSG_ID_GLOBAL_POSITION_INT, MSG.MAVLINK_MSG_ID_LOCAL_POSITION_NED),
    10: (MSG.MAVLINK_MSG_ID_ATTITUDE,),
    11: (MSG.MAVLINK_MSG_ID_VFR_HUD,),
    12: (MSG.MAVLINK_MSG_ID_BATTERY_STATUS, MSG.MAVLINK_MSG_ID_EXTENDED_SYS_STATE),
}
DATA_STREAMS[0] = tuple(i for ids in DATA_STREAMS.values() for i in ids)


@dataclass(slots=True)
class Command:
    """COMMAND_LONG and COMMAND_INT in one shape (``x``/``y`` as degrees for COMMAND_INT positions)."""

    command: int
    params: tuple[float, float, float, float, float, float, float]
    frame: int | None = None  # COMMAND_INT only


@dataclass(slots=True)
class Reply:
    result: MavResult
    extra: list[Message] = field(default_factory=list)


class CommandHandler:
    """Executes commands on ``stack`` at time ``t_s``; ``set_interval`` changes a stream's rate."""

    def __init__(
        self,
        stack: FlightStack,
        encoder: TelemetryEncoder,
        set_interval: Callable[[int, float | None], None],
        get_interval: Callable[[int], float | None],
    ) -> None:
        self.stack = stack
        self.encoder = encoder
        self._set_interval = set_interval
        self._get_interval = get_interval
        self._ap = stack.profile is Profile.ARDUPILOT

    def handle(self, t_s: float, cmd: Command, source: str = "link") -> Reply:
        p = cmd.params
        c = cmd.command
        st = self.stack
        if source == "pilot":
            return self._pilot(t_s, cmd)
        if c == MSG.MAV_CMD_COMPONENT_ARM_DISARM:
            if p[0] >= 0.5:
                return Reply(st.arm(t_s))
            return Reply(st.disarm(t_s, force=int(_or(p[1], 0)) == FORCE_DISARM_MAGIC))
        if c == MSG.MAV_CMD_NAV_TAKEOFF:
            return Reply(st.takeoff(t_s, self._takeoff_alt_m(p[6])))
        if c == MSG.MAV_CMD_NAV_LAND:
            return Reply(st.land(t_s))
        if c == MSG.MAV_CMD_NAV_RETURN_TO_LAUNCH:
            return Reply(st.return_to_launch(t_s))
        if c == MSG.MAV_CMD_DO_SET_MODE:
            mode = self._decode_mode(p)
            return Reply(MavResult.DENIED if mode is None else st.set_mode(t_s, mode, "command"))
        if c == MSG.MAV_CMD_REQUEST_MESSAGE:
            return self._request_message(int(_or(p[0], -1)))
        if c == MSG.MAV_CMD_REQUEST_AUTOPILOT_CAPABILITIES:
            return Reply(MavResult.ACCEPTED, [self.encoder.autopilot_version()])
        if c == MSG.MAV_CMD_SET_MESSAGE_INTERVAL:
            return Reply(self._message_interval(int(_or(p[0], -1)), _or(p[1], 0.0)))
        if c == MSG.MAV_CMD_GET_MESSAGE_INTERVAL:
            msg_id = int(_or(p[0], -1))
            interval_s = self._get_interval(msg_id)
            interval_us = -1 if interval_s is None else int(interval_s * 1e6)
            return Reply(MavResult.ACCEPTED, [self.encoder.message_interval(msg_id, interval_us)])
        if c == MSG.MAV_CMD_DO_REPOSITION:
            return Reply(st.reposition(t_s, self._reposition_target(cmd)))
        if c == MSG.MAV_CMD_DO_GRIPPER:
            return Reply(st.set_gripper(t_s, grab=int(_or(p[1], 0)) == MSG.GRIPPER_ACTION_GRAB))
        if c == MSG.MAV_CMD_DO_CHANGE_SPEED:
            return Reply(self._change_speed(_or(p[1], -1.0)))
        return Reply(MavResult.UNSUPPORTED)

    def param_message(self, msg: Message) -> tuple[list[Message], Param | None]:
        """PARAM_REQUEST_LIST/_READ/PARAM_SET → the PARAM_VALUEs to send, and the parameter set (if any).

        Unknown names get no PARAM_VALUE (as on PX4: the client times out), a set one a STATUSTEXT.
        """
        store = self.stack.params
        kind = msg.get_type()
        if kind == "PARAM_REQUEST_LIST":
            return [self.encoder.param_value(p) for p in store.all()], None
        if kind == "PARAM_REQUEST_READ":
            found = store.by_index(msg.param_index) if msg.param_index >= 0 else store.param(msg.param_id)
            return ([self.encoder.param_value(found)] if found else []), None
        if kind == "PARAM_SET":
            found = store.param(msg.param_id)
            if found is None:
                return [self.encoder.statustext(f"[pm] unknown param: {msg.param_id}", 4)], None
            changed = store.set(found.name, store.decode(msg.param_value, msg.param_type))
            return [self.encoder.param_value(found)], (found if changed else None)
        return [], None

    def _pilot(self, t_s: float, cmd: Command) -> Reply:
        """The pilot/GCS port: mode switches (and arm/disarm) as an RC pilot makes them."""
        if cmd.command == MSG.MAV_CMD_DO_SET_MODE:
            mode = self._decode_mode(cmd.params)
            if mode is None or mode not in PILOT_MODES:
                return Reply(MavResult.DENIED)
            return Reply(self.stack.set_mode(t_s, mode, "pilot"))
        if cmd.command == MSG.MAV_CMD_COMPONENT_ARM_DISARM:
            if cmd.params[0] >= 0.5:
                return Reply(self.stack.arm(t_s))
            return Reply(self.stack.disarm(t_s, force=int(_or(cmd.params[1], 0)) == FORCE_DISARM_MAGIC))
        return Reply(MavResult.UNSUPPORTED)

    def _decode_mode(self, p: tuple[float, ...]) -> Mode | None:
        base = int(_or(p[0], 0))
        if not base & MSG.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED:
            return None
        return mode_from_set_mode_params(self.stack.profile, p[1], p[2])

    def _takeoff_alt_m(self, param7: float) -> float | None:
        """Metres above home; ``None`` → the autopilot's default (PX4 MIS_TAKEOFF_ALT)."""
        if math.isnan(param7):
            return None
        if self._ap:
            return param7
        home = self.stack.home_geo
        if home is None or param7 == 0.0:
            return None
        rel_m = param7 - home.alt_m  # PX4: param7 is AMSL
        return rel_m if rel_m > 0.0 else None

    def _request_message(self, msg_id: int) -> Reply:
        if msg_id == MSG.MAVLINK_MSG_ID_HOME_POSITION:
            home = self.encoder.home_position()
            return Reply(MavResult.ACCEPTED if home else MavResult.TEMPORARILY_REJECTED, [home] if home else [])
        msg = self.encoder.message(msg_id)
        if msg is None:
            return Reply(MavResult.UNSUPPORTED)
        return Reply(MavResult.ACCEPTED, [msg])

    def _message_interval(self, msg_id: int, interval_us: float) -> MavResult:
        if msg_id == MSG.MAVLINK_MSG_ID_HEARTBEAT:
            return MavResult.FAILED  # always 1 Hz: PX4's set_message_interval refuses HEARTBEAT
        if not self.encoder.streamable(msg_id):
            return MavResult.DENIED
        if interval_us < 0:
            self._set_interval(msg_id, None)
        elif interval_us == 0:
            self._set_interval(msg_id, 0.0)  # the default rate
        else:
            self._set_interval(msg_id, max(interval_us / 1e6, 1.0 / MAX_RATE_HZ))
        return MavResult.ACCEPTED

    def _reposition_target(self, cmd: Command) -> tuple[float, float, float]:
        st = self.stack
        here = st.dyn.estimate.pos_ned_m
        lat, lon, alt = cmd.params[4], cmd.params[5], cmd.params[6]
        if cmd.frame is not None:  # COMMAND_INT: x, y in degE7
            lat, lon = lat / 1e7, lon / 1e7
        home = st.home_geo or st.origin
        if cmd.frame in (MSG.MAV_FRAME_GLOBAL_RELATIVE_ALT, MSG.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT):
            alt = home.alt_m + alt if not math.isnan(alt) else alt
        here_geo = st.origin.offset(here)
        target = GeoPoint(
            here_geo.lat_deg if math.isnan(lat) else lat,
            here_geo.lon_deg if math.isnan(lon) else lon,
            here_geo.alt_m if math.isnan(alt) else alt,
        )
        return st.origin.ned_to(target)

    def _change_speed(self, speed_mps: float) -> MavResult:
        if speed_mps <= 0.0:
            return MavResult.DENIED
        store = self.stack.params
        name, value = ("WPNAV_SPEED", speed_mps * 100.0) if self._ap else ("MPC_XY_CRUISE", speed_mps)
        return MavResult.ACCEPTED if store.set(name, value) else MavResult.FAILED


def _or(value: float, default: float) -> float:
    """NaN (PX4's 'unset') → ``default``."""
    return default if math.isnan(value) else value
