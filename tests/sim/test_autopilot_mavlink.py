"""The MAVLink endpoint on the wire (pymavlink as the client): heartbeats, ACKs, rates, params, failsafe."""

from __future__ import annotations

import math
import socket
import time
from collections.abc import Callable, Iterator

import pytest
from pymavlink.dialects.v20 import common as mavlink
from pymavlink.dialects.v20 import development

from sim import pilot
from sim.autopilot import SimAutopilot, SimConfig
from sim.autopilot_modes import Mode, Profile
from sim.estimator import PERFECT
from sim.wind import WindConfig
from tests.sim.conftest import free_udp_port

MSG = mavlink
Message = mavlink.MAVLink_message
HOLD_CUSTOM_MODE = Mode.AUTO_LOITER.custom_mode


class Gcs:
    """A bare MAVLink client listening where the simulator sends (like MAVSDK's udpin)."""

    def __init__(self, port: int, sysid: int = 77, compid: int = 42) -> None:
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sock.bind(("127.0.0.1", port))
        self.tx = mavlink.MAVLink(None, srcSystem=sysid, srcComponent=compid)
        self.rx = development.MAVLink(None)  # common + CURRENT_MODE
        self.rx.robust_parsing = True
        self.peer: tuple[str, int] | None = None

    def messages(self, seconds: float) -> Iterator[Message]:
        deadline = time.monotonic() + seconds
        while (left := deadline - time.monotonic()) > 0:
            self.sock.settimeout(left)
            try:
                data, addr = self.sock.recvfrom(65535)
            except TimeoutError:
                return
            self.peer = addr
            yield from self.rx.parse_buffer(data) or []

    def wait(self, kind: str, timeout_s: float = 3.0, where: Callable[[Message], bool] = lambda _: True) -> Message:
        for msg in self.messages(timeout_s):
            if msg.get_type() == kind and where(msg):
                return msg
        raise AssertionError(f"no {kind} within {timeout_s} s")

    def send(self, msg: Message) -> None:
        if self.peer is None:
            self.wait("HEARTBEAT")
        assert self.peer is not None
        self.sock.sendto(msg.pack(self.tx), self.peer)

    def command(self, command: int, *params: float, timeout_s: float = 2.0) -> Message:
        p = [*params, *[math.nan] * (7 - len(params))]
        self.send(self.tx.command_long_encode(1, 1, command, 0, *p))
        return self.wait("COMMAND_ACK", timeout_s, lambda m: m.command == command)

    def setpoint(self, vn: float, ve: float, vd: float) -> None:
        self.send(
            self.tx.set_position_target_local_ned_encode(
                0, 1, 1, MSG.MAV_FRAME_LOCAL_NED, 0x9C7, 0, 0, 0, vn, ve, vd, 0, 0, 0, 0.0, 0.0
            )
        )

    def count(self, kind: str, seconds: float) -> int:
        return sum(1 for m in self.messages(seconds) if m.get_type() == kind)

    def close(self) -> None:
        self.sock.close()


@pytest.fixture
def link(request: pytest.FixtureRequest) -> Iterator[tuple[SimAutopilot, Gcs]]:
    config = getattr(request, "param", {})
    port = free_udp_port()
    gcs = Gcs(port)
    sim = SimAutopilot(SimConfig(target=("127.0.0.1", port), pilot_port=0, wind=WindConfig.off(), **config))
    sim.start()
    yield sim, gcs
    sim.stop()
    gcs.close()


def test_heartbeat_says_px4_quadrotor_in_hold_with_custom_mode_enabled(link: tuple[SimAutopilot, Gcs]) -> None:
    _, gcs = link
    hb = gcs.wait("HEARTBEAT")
    assert hb.get_srcSystem() == 1 and hb.get_srcComponent() == 1
    assert (hb.type, hb.autopilot) == (MSG.MAV_TYPE_QUADROTOR, MSG.MAV_AUTOPILOT_PX4)
    assert hb.base_mode & MSG.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED
    assert not hb.base_mode & MSG.MAV_MODE_FLAG_SAFETY_ARMED
    assert hb.custom_mode == HOLD_CUSTOM_MODE == 0x03040000
    assert hb.get_header().mlen == 9 and hb._header.incompat_flags == 0  # MAVLink 2


def test_every_command_is_acked_to_its_sender(link: tuple[SimAutopilot, Gcs]) -> None:
    _, gcs = link
    gcs.wait("SYS_STATUS", where=lambda m: m.onboard_control_sensors_health & MSG.MAV_SYS_STATUS_PREARM_CHECK)
    ack = gcs.command(31999)  # nobody knows this one
    assert ack.result == MSG.MAV_RESULT_UNSUPPORTED
    assert (ack.target_system, ack.target_component) == (77, 42)
    gcs.send(gcs.tx.command_int_encode(1, 1, 0, MSG.MAV_CMD_DO_SET_MODE, 0, 0, 1, 3, 0, 0, 0, 0, 0))
    ack = gcs.wait("COMMAND_ACK", where=lambda m: m.command == MSG.MAV_CMD_DO_SET_MODE)
    assert ack.result == MSG.MAV_RESULT_ACCEPTED  # POSCTL through COMMAND_INT
    assert gcs.wait("HEARTBEAT", 1.2).custom_mode == Mode.POSCTL.custom_mode  # with the next 1 Hz heartbeat


def test_heartbeat_is_1_hz_whatever_happens_and_current_mode_tells_a_switch_at_once(
    link: tuple[SimAutopilot, Gcs],
) -> None:
    sim, gcs = link
    gcs.wait("SYS_STATUS", where=lambda m: m.onboard_control_sensors_health & MSG.MAV_SYS_STATUS_PREARM_CHECK)
    # PX4 refuses a faster HEARTBEAT; CURRENT_MODE (PX4 ≥ 1.15) is off until asked for, then at most 20 Hz and
    # only when something changed or 0.5 s passed (PX4 sends it when vehicle_status was published).
    assert gcs.command(MSG.MAV_CMD_SET_MESSAGE_INTERVAL, MSG.MAVLINK_MSG_ID_HEARTBEAT, 50_000).result == (
        MSG.MAV_RESULT_FAILED
    )
    assert gcs.count("CURRENT_MODE", 0.6) == 0
    ack = gcs.command(MSG.MAV_CMD_SET_MESSAGE_INTERVAL, development.MAVLINK_MSG_ID_CURRENT_MODE, 50_000)
    assert ack.result == MSG.MAV_RESULT_ACCEPTED
    counts: dict[str, int] = {}
    for m in gcs.messages(2.05):
        counts[m.get_type()] = counts.get(m.get_type(), 0) + 1
    assert 2 <= counts.get("HEARTBEAT", 0) <= 3 and 4 <= counts.get("CURRENT_MODE", 0) <= 6
    assert sim.pilot_address is not None
    assert pilot.set_mode("POSCTL", port=sim.pilot_address[1]).ok
    switched = time.monotonic()
    current = gcs.wait("CURRENT_MODE", 0.5, lambda m: m.custom_mode == Mode.POSCTL.custom_mode)
    seen_s = time.monotonic() - switched
    print(f"CURRENT_MODE showed the pilot's switch after {seen_s * 1000:.0f} ms")
    assert seen_s < 0.5  # 20 Hz stream; generous for a loaded machine (the 1 Hz HEARTBEAT is not what was awaited)
    assert (current.standard_mode, current.intended_custom_mode) == (1, Mode.POSCTL.custom_mode)  # POSITION_HOLD
    beats = [m for m in gcs.messages(2.5) if m.get_type() == "HEARTBEAT"]
    assert 2 <= len(beats) <= 3  # the switch did not bring one forward


@pytest.mark.parametrize("link", [{"profile": Profile.ARDUPILOT}], indirect=True)
def test_ardupilot_has_no_current_mode(link: tuple[SimAutopilot, Gcs]) -> None:
    _, gcs = link
    ack = gcs.command(MSG.MAV_CMD_SET_MESSAGE_INTERVAL, development.MAVLINK_MSG_ID_CURRENT_MODE, 50_000)
    assert ack.result == MSG.MAV_RESULT_DENIED


def test_set_message_interval_changes_and_disables_a_stream(link: tuple[SimAutopilot, Gcs]) -> None:
    _, gcs = link
    assert 20 <= gcs.count("LOCAL_POSITION_NED", 1.0) <= 36  # PX4 SITL streams unasked
    ack = gcs.command(MSG.MAV_CMD_SET_MESSAGE_INTERVAL, MSG.MAVLINK_MSG_ID_LOCAL_POSITION_NED, 20_000)
    assert ack.result == MSG.MAV_RESULT_ACCEPTED
    assert 40 <= gcs.count("LOCAL_POSITION_NED", 1.0) <= 55
    gcs.command(MSG.MAV_CMD_SET_MESSAGE_INTERVAL, MSG.MAVLINK_MSG_ID_LOCAL_POSITION_NED, -1)
    gcs.count("LOCAL_POSITION_NED", 0.1)  # what was already under way
    assert gcs.count("LOCAL_POSITION_NED", 0.5) == 0
    assert gcs.command(MSG.MAV_CMD_SET_MESSAGE_INTERVAL, 12345, 100_000).result == MSG.MAV_RESULT_DENIED


@pytest.mark.parametrize("link", [{"estimator": PERFECT}], indirect=True)  # home exactly at the origin
def test_request_message_answers_home_and_autopilot_version(link: tuple[SimAutopilot, Gcs]) -> None:
    _, gcs = link
    gcs.wait("SYS_STATUS", where=lambda m: m.onboard_control_sensors_health & MSG.MAV_SYS_STATUS_PREARM_CHECK)
    assert gcs.command(MSG.MAV_CMD_REQUEST_MESSAGE, MSG.MAVLINK_MSG_ID_HOME_POSITION).result == 0
    home = gcs.wait("HOME_POSITION")
    assert home.latitude == int(63.62831245 * 1e7) and home.altitude == 50_000
    assert gcs.command(MSG.MAV_CMD_REQUEST_AUTOPILOT_CAPABILITIES).result == 0
    version = gcs.wait("AUTOPILOT_VERSION")
    assert version.capabilities & MSG.MAV_PROTOCOL_CAPABILITY_PARAM_ENCODE_BYTEWISE
    assert version.flight_sw_version >> 16 == (1 << 8) | 15  # PX4 1.15


def test_params_list_read_and_set(link: tuple[SimAutopilot, Gcs]) -> None:
    sim, gcs = link
    gcs.send(gcs.tx.param_request_list_encode(1, 1))
    values = [m for m in gcs.messages(0.5) if m.get_type() == "PARAM_VALUE"]
    assert {v.param_index for v in values} == set(range(len(sim.stack.params)))
    gcs.send(gcs.tx.param_request_read_encode(1, 1, b"SYS_AUTOSTART", -1))
    value = gcs.wait("PARAM_VALUE", where=lambda m: m.param_id == "SYS_AUTOSTART")
    assert value.param_type == MSG.MAV_PARAM_TYPE_INT32
    assert sim.stack.params.decode(value.param_value, value.param_type) == 10015
    gcs.send(gcs.tx.param_set_encode(1, 1, b"MIS_TAKEOFF_ALT", 7.5, MSG.MAV_PARAM_TYPE_REAL32))
    echo = gcs.wait("PARAM_VALUE", where=lambda m: m.param_id == "MIS_TAKEOFF_ALT")
    assert echo.param_value == 7.5 and sim.stack.tuning.takeoff_alt_m() == 7.5


def test_ping_and_timesync_are_answered(link: tuple[SimAutopilot, Gcs]) -> None:
    _, gcs = link
    gcs.send(gcs.tx.ping_encode(123456, 9, 0, 0))
    pong = gcs.wait("PING")
    assert (pong.time_usec, pong.seq, pong.target_system, pong.target_component) == (123456, 9, 77, 42)
    gcs.send(gcs.tx.timesync_encode(0, 987654321))
    sync = gcs.wait("TIMESYNC")
    assert sync.ts1 == 987654321 and sync.tc1 > 0


@pytest.mark.parametrize("link", [{"params": {"MIS_TAKEOFF_ALT": 1.0}}], indirect=True)
def test_offboard_loss_switches_to_hold_one_second_after_the_last_setpoint(link: tuple[SimAutopilot, Gcs]) -> None:
    _, gcs = link
    gcs.wait("SYS_STATUS", where=lambda m: m.onboard_control_sensors_health & MSG.MAV_SYS_STATUS_PREARM_CHECK)
    assert gcs.command(MSG.MAV_CMD_COMPONENT_ARM_DISARM, 1).result == 0
    assert gcs.command(MSG.MAV_CMD_NAV_TAKEOFF).result == 0
    gcs.wait("HEARTBEAT", 10.0, lambda m: m.custom_mode == HOLD_CUSTOM_MODE)  # takeoff done
    for _ in range(5):
        gcs.setpoint(1.0, 0.0, 0.0)
        time.sleep(0.05)
    assert gcs.command(MSG.MAV_CMD_DO_SET_MODE, 1, 6, 0).result == 0
    for _ in range(10):
        time.sleep(0.05)
        gcs.setpoint(1.0, 0.0, 0.0)
    last_setpoint = time.monotonic()
    texts = []
    for msg in gcs.messages(3.0):
        if msg.get_type() == "STATUSTEXT":
            texts.append(msg.text)
        if msg.get_type() == "HEARTBEAT" and msg.custom_mode == HOLD_CUSTOM_MODE:
            break
    took_s = time.monotonic() - last_setpoint
    print(f"HOLD {took_s:.3f} s after the last setpoint (COM_OF_LOSS_T 1.0 s)")
    assert 0.98 <= took_s <= 3.0  # never early; the upper bound is generous for a loaded machine
    assert any("offboard lost" in text for text in texts)


def test_disarm_in_air_is_denied_unless_forced(link: tuple[SimAutopilot, Gcs]) -> None:
    _, gcs = link
    gcs.wait("SYS_STATUS", where=lambda m: m.onboard_control_sensors_health & MSG.MAV_SYS_STATUS_PREARM_CHECK)
    gcs.command(MSG.MAV_CMD_COMPONENT_ARM_DISARM, 1)
    gcs.command(MSG.MAV_CMD_NAV_TAKEOFF)
    gcs.wait("EXTENDED_SYS_STATE", 5.0, lambda m: m.landed_state == MSG.MAV_LANDED_STATE_TAKEOFF)
    assert gcs.command(MSG.MAV_CMD_COMPONENT_ARM_DISARM, 0).result == MSG.MAV_RESULT_DENIED
    assert gcs.command(MSG.MAV_CMD_COMPONENT_ARM_DISARM, 0, 21196).result == MSG.MAV_RESULT_ACCEPTED
    hb = gcs.wait("HEARTBEAT", 0.5)
    assert not hb.base_mode & MSG.MAV_MODE_FLAG_SAFETY_ARMED


def test_pilot_port_switches_modes_and_heartbeats_back(link: tuple[SimAutopilot, Gcs]) -> None:
    sim, gcs = link
    assert sim.pilot_address is not None
    port = sim.pilot_address[1]
    status = pilot.status(port=port)
    assert status.ok and status.mode is Mode.AUTO_LOITER
    gcs.wait("SYS_STATUS", where=lambda m: m.onboard_control_sensors_health & MSG.MAV_SYS_STATUS_PREARM_CHECK)
    result = pilot.set_mode("POSCTL", port=port)
    assert result.ok and result.mode is Mode.POSCTL
    assert pilot.set_mode("OFFBOARD", port=port).ok is False  # no setpoint stream
    assert pilot.set_mode("RTL", port=port).ok
    assert pilot.status(port=port).mode is Mode.AUTO_RTL
    assert not pilot.set_mode("BOGUS", port=port).ok


@pytest.mark.parametrize("link", [{"profile": Profile.ARDUPILOT}], indirect=True)
def test_ardupilot_streams_only_heartbeat_until_asked(link: tuple[SimAutopilot, Gcs]) -> None:
    _, gcs = link
    kinds = {m.get_type() for m in gcs.messages(1.5)}
    assert kinds == {"HEARTBEAT"}
    hb = gcs.wait("HEARTBEAT")
    assert hb.autopilot == MSG.MAV_AUTOPILOT_ARDUPILOTMEGA and hb.custom_mode == 0  # STABILIZE
    gcs.send(gcs.tx.request_data_stream_encode(1, 1, 6, 10, 1))  # POSITION group at 10 Hz
    assert 7 <= gcs.count("GLOBAL_POSITION_INT", 1.0) <= 12
    gcs.send(gcs.tx.param_request_read_encode(1, 1, b"DISARM_DELAY", -1))
    assert gcs.wait("PARAM_VALUE").param_value == 10.0  # cast encoding
    assert pilot.set_mode("HOLD", port=link[0].pilot_address[1]).mode is Mode.AP_LOITER  # type: ignore[index]
