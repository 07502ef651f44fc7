"""The simulated autopilot's MAVLink endpoint (PX4 or ArduCopter dialect), in real time.

Like PX4 SITL it *sends* to a UDP address where MAVSDK listens (``udpin://0.0.0.0:14540``) from one
socket and answers from that same socket: MAVLink 2, sysid 1, compid 1. A second socket, the pilot/GCS
port (bound on 127.0.0.1), takes mode switches from a pilot tool (``sim.pilot``) and heartbeats back to
whoever spoke to it (both in ``sim.autopilot_link``). One thread does everything on the wall clock
(``time.monotonic``): it wakes at ``tick_hz`` (and on every packet), steps the physics in 10 ms substeps
(100 Hz), sends the telemetry streams that are due and answers commands as they arrive. See
``sim.state_log`` for the JSON-lines log and ``sim.autopilot`` for the command line.

Embedded (tests)::

    with SimAutopilot(SimConfig(target=("127.0.0.1", port), pilot_port=0)) as sim:
        ...  # sim.truth(), sim.pilot_address, sim.submit(lambda stack: ...)
"""

from __future__ import annotations

import logging
import math
import queue
import select
import socket
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field

from pymavlink.dialects.v20 import common as mavlink

from sim import airframes
from sim.autopilot_commands import DATA_STREAMS, Command, CommandHandler
from sim.autopilot_link import Address, Link, open_links
from sim.autopilot_modes import DEFAULT_ORIGIN, GeoPoint, Profile, mode_from_custom
from sim.autopilot_telemetry import DEFAULT_RATES_HZ, STREAMABLE, Message, TelemetryEncoder
from sim.dynamics import Dynamics
from sim.estimator import EstimatorError, EstimatorErrorParams
from sim.flight_stack import FlightStack
from sim.multirotor import MultirotorParams
from sim.stack_types import PositionTarget, StackEvent, Truth
from sim.state_log import StateLog
from sim.wind import Wind, WindConfig

MSG = mavlink
log = logging.getLogger("sim.autopilot")  # the endpoint's logger, as the program names it
TRUTH_LOG_PERIOD_S = 0.1
HEARTBEAT_PERIOD_S = 1.0


@dataclass(frozen=True)
class SimConfig:
    """How to run the simulated autopilot; ``pilot_port`` None disables it, 0 picks a free port."""

    target: Address = ("127.0.0.1", 14540)
    pilot_port: int | None = 14580
    profile: Profile = Profile.PX4
    seed: int = 0
    wind: WindConfig = field(default_factory=WindConfig)
    origin: GeoPoint = DEFAULT_ORIGIN
    state_log: str | None = None
    tick_hz: float = 100.0  # wake-ups of the loop; the physics substeps at 100 Hz within each
    gps_fix_delay_s: float = 1.0
    params: dict[str, float] | None = None
    airframe: MultirotorParams | None = None  # None: the calibrated airframe for ``profile`` (sim.airframes)
    estimator: EstimatorErrorParams | None = None  # None: the calibrated estimator error for ``profile``


class SimAutopilot:
    """The endpoint; ``start()``/``stop()`` run it in a thread, ``run(stop_event)`` in the caller's."""

    def __init__(self, config: SimConfig | None = None) -> None:
        self.config = c = config if config is not None else SimConfig()
        self._main, self._pilot = open_links(c.target, c.pilot_port)
        self._state_log: StateLog | None = StateLog(c.state_log) if c.state_log else None
        calibrated = airframes.default_for(c.profile)
        dynamics = Dynamics(
            c.airframe if c.airframe is not None else calibrated.airframe,
            Wind(c.wind, seed=c.seed),
            estimator=EstimatorError(c.estimator if c.estimator is not None else calibrated.estimator, c.seed),
        )
        self.stack = FlightStack(dynamics, c.profile, c.origin, c.params, c.gps_fix_delay_s, on_event=self._on_event)
        self.encoder = TelemetryEncoder(self.stack)
        self.commands = CommandHandler(self.stack, self.encoder, self._set_interval, self._get_interval)
        self._t0 = time.monotonic()
        ap = c.profile is Profile.ARDUPILOT
        self._interval_s: dict[int, float | None] = {
            i: (None if ap or hz <= 0.0 else 1.0 / hz) for i, hz in DEFAULT_RATES_HZ.items()
        }
        self._next_due_s: dict[int, float] = dict.fromkeys(STREAMABLE, 0.0)
        self._next_heartbeat_s = 0.0
        self._pilot_heartbeat_now = False
        self._next_truth_log_s = 0.0
        self._truth: Truth | None = None
        self._jobs: queue.SimpleQueue[Callable[[FlightStack], None]] = queue.SimpleQueue()
        self._observers: list[Callable[[Truth], None]] = []
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._log(
            "start",
            profile=c.profile.value,
            seed=c.seed,
            target=f"{c.target[0]}:{c.target[1]}",
            pilot_port=self.pilot_address[1] if self.pilot_address else 0,
            home=[c.origin.lat_deg, c.origin.lon_deg, c.origin.alt_m],
            boot_monotonic_s=round(self._t0, 6),  # t_s + this = CLOCK_MONOTONIC (the app's loop clock)
        )
        self._log("mode", mode=self.stack.mode.flight_mode.value, autopilot_mode=self.stack.mode.label, reason="boot")

    # -- public ---------------------------------------------------------------------------------

    @property
    def pilot_address(self) -> Address | None:
        return None if self._pilot is None else self._pilot.local_address

    @property
    def boot_monotonic_s(self) -> float:
        """``time.monotonic()`` at boot: time_boot_ms counts from here, and so does the state log's ``t_s``."""
        return self._t0

    def truth(self) -> Truth | None:
        """The latest truth snapshot (safe to call from any thread)."""
        return self._truth

    def add_observer(self, observer: Callable[[Truth], None]) -> None:
        """Call ``observer(truth)`` in the endpoint's thread after every physics tick (the simulated world: the
        sea, the object, the sensors that need the vehicle). Add observers before ``start()``/``run()``."""
        self._observers.append(observer)

    def log(self, event: str, t_s: float | None = None, **fields: object) -> None:
        """A record in the state log (from the endpoint's thread: an observer)."""
        self._log(event, t_s, **fields)

    def submit(self, job: Callable[[FlightStack], None]) -> None:
        """Run ``job(stack)`` in the endpoint's thread at its next tick (e.g. to inject a failure)."""
        self._jobs.put(job)

    def start(self) -> None:
        self._thread = threading.Thread(target=self.run, args=(self._stop,), name="sim.autopilot", daemon=True)
        self._thread.start()

    def stop(self) -> None:
        self._stop.set()
        if self._thread is not None and self._thread is not threading.current_thread():
            self._thread.join(timeout=5.0)
        self._close()

    def __enter__(self) -> SimAutopilot:
        self.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop()

    def run(self, stop: threading.Event) -> None:
        """The loop: wait for packets until the next physics tick, then tick. Returns when ``stop`` is set."""
        dt_s = 1.0 / self.config.tick_hz
        socks = [self._main.sock] + ([self._pilot.sock] if self._pilot else [])
        next_tick = time.monotonic()
        while not stop.is_set():
            try:
                readable, _, _ = select.select(socks, [], [], max(0.0, next_tick - time.monotonic()))
            except (OSError, ValueError):
                break  # sockets closed under us
            for sock in readable:
                self._drain(sock)
            now = time.monotonic()
            if now >= next_tick:
                self._tick(now - self._t0)
                next_tick += dt_s
                if now - next_tick > 0.1:  # fell far behind (machine busy): don't try to catch up
                    next_tick = now + dt_s

    # -- the tick -------------------------------------------------------------------------------

    def _now_s(self) -> float:
        return time.monotonic() - self._t0

    def _tick(self, t_s: float) -> None:
        while not self._jobs.empty():
            self._jobs.get_nowait()(self.stack)
        self.stack.step(t_s)
        self._truth = self.stack.truth()
        for observer in self._observers:
            observer(self._truth)
        if t_s >= self._next_heartbeat_s:
            self._send_heartbeats()  # 1 Hz and never sooner, like PX4's const-rate HEARTBEAT stream
        if self._pilot_heartbeat_now:
            self._send_pilot_heartbeat()
        for msg_id, interval_s in self._interval_s.items():
            if interval_s is None or t_s < self._next_due_s[msg_id]:
                continue
            due = self._next_due_s[msg_id] + interval_s
            self._next_due_s[msg_id] = due if due > t_s else t_s + interval_s
            msg = self.encoder.stream(msg_id, t_s)
            if msg is not None:
                self._main.send(msg)
        if self._state_log is not None and t_s >= self._next_truth_log_s:
            self._next_truth_log_s = t_s + TRUTH_LOG_PERIOD_S
            tr = self._truth
            self._state_log.write(
                "truth",
                t_s,
                pos_ned_m=tr.pos_ned_m,
                vel_ned_mps=tr.vel_ned_mps,
                att_rad=(tr.roll_rad, tr.pitch_rad, tr.yaw_rad),
                mode=tr.flight_mode.value,
                armed=tr.armed,
                landed_state=tr.landed_state.value,
                wind_ned_mps=tr.wind_ned_mps,
                battery_v=tr.battery_v,
                battery_remaining=tr.battery_remaining,
            )

    def _send_heartbeats(self) -> None:
        self._next_heartbeat_s = self._now_s() + HEARTBEAT_PERIOD_S
        self._main.send(self.encoder.heartbeat())
        self._send_pilot_heartbeat()

    def _send_pilot_heartbeat(self) -> None:
        """The pilot tool stands in for the RC link: it hears of a mode or arming change at once."""
        self._pilot_heartbeat_now = False
        if self._pilot is not None:
            self._pilot.send(self.encoder.heartbeat())

    def _set_interval(self, msg_id: int, interval_s: float | None) -> None:
        """``None`` stops the stream, 0 = the default rate (PX4 SITL's; 1 Hz for one PX4 does not stream)."""
        if interval_s == 0.0:
            default_hz = DEFAULT_RATES_HZ[msg_id]
            interval_s = 1.0 / default_hz if default_hz > 0.0 else 1.0
        self._interval_s[msg_id] = interval_s
        self._next_due_s[msg_id] = self._now_s()

    def _get_interval(self, msg_id: int) -> float | None:
        return self._interval_s.get(msg_id)

    # -- events from the stack ------------------------------------------------------------------

    def _on_event(self, ev: StackEvent) -> None:
        if ev.kind in ("mode", "armed"):
            self._pilot_heartbeat_now = True
        if ev.kind == "mode" and ev.mode is not None:
            self._log("mode", ev.t_s, mode=ev.mode.flight_mode.value, autopilot_mode=ev.mode.label, reason=ev.reason)
        elif ev.kind == "armed":
            self._log("armed", ev.t_s, armed=ev.armed, reason=ev.reason)
        elif ev.kind == "landed_state" and ev.landed_state is not None:
            self._log("landed_state", ev.t_s, landed_state=ev.landed_state.value)
        elif ev.kind == "statustext":
            self._log("statustext", ev.t_s, text=ev.text, severity=ev.severity)
            self._main.send(self.encoder.statustext(ev.text, ev.severity))
        elif ev.kind == "home":
            self._log("home", ev.t_s, home_ned_m=self.stack.home_ned_m)
            home = self.encoder.home_position()
            if home is not None and self._interval_s[MSG.MAVLINK_MSG_ID_HOME_POSITION] is not None:
                self._main.send(home)
        elif ev.kind == "gripper":
            self._log("gripper", ev.t_s, action=ev.text)

    def _log(self, event: str, t_s: float | None = None, **fields: object) -> None:
        if self._state_log is not None:
            self._state_log.write(event, self._now_s() if t_s is None else t_s, **fields)

    # -- incoming -------------------------------------------------------------------------------

    def _drain(self, sock: socket.socket) -> None:
        link = self._main if sock is self._main.sock else self._pilot
        assert link is not None
        for addr, data in link.datagrams():
            if link.note_peer(addr) and link is self._pilot:
                link.send(self.encoder.heartbeat(), addr)  # answer a new pilot at once
            for msg in link.parse(data):
                try:
                    self._handle(link, addr, msg)
                except Exception:
                    log.exception("failed to handle %s", msg.get_type())
            self._truth = self.stack.truth()  # commands may have changed it since the tick
            if self._pilot_heartbeat_now:
                self._send_pilot_heartbeat()

    def _handle(self, link: Link, addr: Address, msg: Message) -> None:
        kind = msg.get_type()
        pilot = link is self._pilot
        t_s = self._now_s()
        if kind in ("COMMAND_LONG", "COMMAND_INT"):
            if not pilot and (msg.target_system not in (0, 1) or msg.target_component not in (0, 1)):
                return
            self._command(link, addr, msg, t_s, "pilot" if pilot else "link")
        elif pilot:
            return  # the pilot port only takes commands
        elif kind == "SET_POSITION_TARGET_LOCAL_NED" and msg.target_system in (0, 1):
            self._log(
                "setpoint",
                t_s,
                vel_ned_mps=(msg.vx, msg.vy, msg.vz),
                yaw_rad=msg.yaw,
                type_mask=msg.type_mask,
                frame=msg.coordinate_frame,
                mode=self.stack.flight_mode.value,
            )
            self.stack.position_target(
                t_s,
                PositionTarget(
                    msg.coordinate_frame,
                    msg.type_mask,
                    (msg.x, msg.y, msg.z),
                    (msg.vx, msg.vy, msg.vz),
                    msg.yaw,
                    msg.yaw_rate,
                ),
            )
        elif kind == "SET_MODE" and msg.target_system in (0, 1):
            mode = mode_from_custom(self.config.profile, msg.custom_mode)
            if mode is not None and msg.base_mode & MSG.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED:
                self.stack.set_mode(t_s, mode, "command")
        elif kind.startswith("PARAM_"):
            self._param(link, msg, t_s)
        elif kind == "PING" and msg.target_system == 0:
            link.send(self.encoder.ping_reply(msg), addr)
        elif kind == "TIMESYNC" and msg.tc1 == 0:
            link.send(self.encoder.timesync_reply(int(t_s * 1e9), msg.ts1), addr)
        elif kind == "REQUEST_DATA_STREAM" and msg.target_system in (0, 1):
            rate_hz = min(float(msg.req_message_rate), 50.0)
            for msg_id in DATA_STREAMS.get(msg.req_stream_id, ()):
                self._set_interval(msg_id, 1.0 / rate_hz if msg.start_stop and rate_hz > 0 else None)

    def _command(self, link: Link, addr: Address, msg: Message, t_s: float, source: str) -> None:
        if msg.get_type() == "COMMAND_INT":
            unset = (0x7FFFFFFF, -0x80000000)
            x = math.nan if msg.x in unset else float(msg.x)
            y = math.nan if msg.y in unset else float(msg.y)
            cmd = Command(msg.command, (msg.param1, msg.param2, msg.param3, msg.param4, x, y, msg.z), msg.frame)
        else:
            cmd = Command(
                msg.command, (msg.param1, msg.param2, msg.param3, msg.param4, msg.param5, msg.param6, msg.param7)
            )
        reply = self.commands.handle(t_s, cmd, source)
        ack = self.encoder.command_ack(msg.command, int(reply.result), msg.get_srcSystem(), msg.get_srcComponent())
        link.send(ack, addr)
        for extra in reply.extra:
            link.send(extra, addr)
        name = MSG.enums["MAV_CMD"][msg.command].name if msg.command in MSG.enums["MAV_CMD"] else str(msg.command)
        self._log(
            "command",
            t_s,
            command=name.removeprefix("MAV_CMD_"),
            result=reply.result.name,
            source=source,
            params=[float(v) for v in cmd.params],
        )

    def _param(self, link: Link, msg: Message, t_s: float) -> None:
        replies, changed = self.commands.param_message(msg)
        for reply in replies:
            link.send(reply)
        if changed is not None:
            self._log("param", t_s, name=changed.name, value=changed.value)

    def _close(self) -> None:
        for link in (self._main, self._pilot):
            if link is not None:
                link.close()
        if self._state_log is not None:
            self._log("stop")
            self._state_log.close()
            self._state_log = None
