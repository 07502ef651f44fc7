"""The flight-safety rules, checked from the vehicle's side: on what the simulated autopilot received.

Input is the vehicle's record list (``sim.inproc.InProcessVehicle.records``, the state-log format:
``setpoint`` with ``vel_ned_mps``/``yaw_rad``/``origin``, ``command`` with ``command``/``mode``/``result``/
``source``, ``mode``/``armed``/``landed_state`` changes) and, for the two facts only the app knows — when
it decided to abort, and how many log records it wrote — the app's event-log lines.

Rules (each violation names the rule):

- ``safe_end``: the run ended with a reason, in the outcome the case expects, and the vehicle is left safe:
  disarmed, or in a mode that holds by itself (HOLD/LOITER/BRAKE, RTL, LAND, or whatever the pilot or the
  autopilot chose), or in OFFBOARD/GUIDED with no non-zero setpoint still arriving (the autopilot's own
  setpoint-loss handling then stops it) — never flying on a velocity that is re-sent with nobody behind it.
- ``no_command_after_takeover``: once the pilot or an autopilot failsafe switched the mode, no mode command
  from the link and no non-zero setpoint reaches the vehicle (after ``grace_s``: what was already in the
  link when the switch happened, the link delay plus one telemetry sample).
- ``zero_before_hold``: every time the link takes the vehicle out of OFFBOARD (a mode command while in
  OFFBOARD), the setpoints of the preceding ``zero_s`` are zero velocity.
- ``finite_in_envelope``: every setpoint is finite (velocity and yaw) and inside the speed envelope.
- ``only_stop_after_abort``: once the app entered its abort state, only zero setpoints and the HOLD command
  reach the vehicle.
- ``watchdog``: no non-zero setpoint is re-sent longer than ``watchdog_s`` (plus one re-send period) after
  the last setpoint the app itself sent.
- ``no_lost_log_record``: the event-log file holds as many lines as the app wrote records.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from typing import Any

from app.messages import FlightMode

RESEND_S = 0.05
EPS = 1e-6

# Modes that fly safely with nobody sending setpoints (ArduPilot BRAKE/LOITER read as HOLD).
SELF_HOLDING = frozenset({FlightMode.HOLD.value, FlightMode.RETURN_TO_LAUNCH.value, FlightMode.LAND.value})
TAKEOVER_REASONS = frozenset({"pilot", "failsafe"})


@dataclass(frozen=True, slots=True)
class Limits:
    max_h_speed_mps: float
    max_up_mps: float
    max_down_mps: float
    zero_s: float  # how long zero velocity goes out before HOLD (exit_zero_s)
    watchdog_s: float


@dataclass(frozen=True, slots=True)
class RunFacts:
    """What the app reports about the run (from its return value and its event log)."""

    outcome: str
    reason: str
    expected_outcomes: frozenset[str]
    abort_t_s: float | None  # when the app entered its abort state, if it did
    log_lines: int  # lines in the event-log file
    log_records: int  # records the app wrote
    grace_s: float  # link delay + one telemetry sample
    end_t_s: float  # the end of the simulation (vehicle clock)


@dataclass(frozen=True, slots=True)
class Violation:
    rule: str
    detail: str


@dataclass
class _Timeline:
    records: Sequence[dict[str, Any]]
    setpoints: list[dict[str, Any]] = field(default_factory=list)

    def __post_init__(self) -> None:
        self.setpoints = [r for r in self.records if r["event"] == "setpoint"]


def _zero(r: dict[str, Any]) -> bool:
    return all(abs(v) <= EPS for v in r["vel_ned_mps"])


def _fmt(r: dict[str, Any]) -> str:
    if r["event"] == "setpoint":
        v = ", ".join(f"{x:.2f}" for x in r["vel_ned_mps"])
        return f"t={r['t_s']:.2f} setpoint ({v}) [{r.get('origin', '?')}]"
    return f"t={r['t_s']:.2f} {r['event']} " + " ".join(f"{k}={v}" for k, v in r.items() if k not in ("t_s", "event"))


def check(records: Sequence[dict[str, Any]], facts: RunFacts, limits: Limits) -> list[Violation]:
    tl = _Timeline(records)
    out: list[Violation] = []
    out += _safe_end(tl, facts)
    out += _no_command_after_takeover(tl, facts)
    out += _zero_before_hold(tl, limits)
    out += _finite_in_envelope(tl, limits)
    out += _only_stop_after_abort(tl, facts)
    out += _watchdog(tl, limits)
    if facts.log_lines != facts.log_records:
        out.append(
            Violation("no_lost_log_record", f"{facts.log_records} records written, {facts.log_lines} in the file")
        )
    return out


def final_vehicle_state(records: Iterable[dict[str, Any]]) -> tuple[str | None, bool]:
    """(flight mode, armed) after the last record."""
    mode, armed = None, False
    for r in records:
        if r["event"] == "mode":
            mode = r["mode"]
        elif r["event"] == "armed":
            armed = bool(r["armed"])
    return mode, armed


def _safe_end(tl: _Timeline, facts: RunFacts) -> list[Violation]:
    out = []
    if not facts.reason:
        out.append(Violation("safe_end", f"outcome {facts.outcome} without a reason"))
    if facts.outcome not in facts.expected_outcomes:
        expected = "/".join(sorted(facts.expected_outcomes))
        out.append(Violation("safe_end", f"outcome {facts.outcome} ({facts.reason}), expected {expected}"))
    mode, armed = final_vehicle_state(tl.records)
    if not armed:
        return out
    if mode == FlightMode.OFFBOARD.value:
        # Still driven by a setpoint stream nobody updates? (Without one, PX4 falls back to HOLD after
        # COM_OF_LOSS_T and ArduCopter GUIDED stops after GUID_TIMEOUT: the autopilot's own handling.)
        live = [s for s in tl.setpoints if s["t_s"] >= facts.end_t_s - 1.0]
        if live and not _zero(live[-1]):
            out.append(Violation("safe_end", f"left in OFFBOARD on {_fmt(live[-1])}, still re-sent"))
    elif mode not in SELF_HOLDING and not _taken_over(tl):
        out.append(Violation("safe_end", f"left armed in {mode}"))
    return out


def _taken_over(tl: _Timeline) -> dict[str, Any] | None:
    return next((r for r in tl.records if r["event"] == "mode" and r.get("reason") in TAKEOVER_REASONS), None)


def _no_command_after_takeover(tl: _Timeline, facts: RunFacts) -> list[Violation]:
    switch = _taken_over(tl)
    if switch is None:
        return []
    after = switch["t_s"] + facts.grace_s
    out = []
    for r in tl.records:
        if r["t_s"] <= after:
            continue
        if r["event"] == "command" and r.get("source") == "link":
            out.append(
                Violation(
                    "no_command_after_takeover",
                    f"{_fmt(r)} after the {switch['reason']} switch to {switch['mode']} at t={switch['t_s']:.2f}",
                )
            )
        elif r["event"] == "setpoint" and not _zero(r):
            out.append(
                Violation(
                    "no_command_after_takeover",
                    f"{_fmt(r)} after the {switch['reason']} switch to {switch['mode']} at t={switch['t_s']:.2f}",
                )
            )
    return out[:3]


def _zero_before_hold(tl: _Timeline, limits: Limits) -> list[Violation]:
    out = []
    mode = None
    for r in tl.records:
        if r["event"] == "mode":
            mode = r["mode"]
        elif (
            r["event"] == "command"
            and r.get("source") == "link"
            and r.get("command") == "DO_SET_MODE"
            and mode == FlightMode.OFFBOARD.value
            and r.get("mode") != FlightMode.OFFBOARD.value
        ):
            window = [s for s in tl.setpoints if r["t_s"] - limits.zero_s + RESEND_S <= s["t_s"] <= r["t_s"]]
            bad = [s for s in window if not _zero(s)]
            if not window or bad:
                detail = _fmt(bad[-1]) if bad else "no setpoint"
                out.append(Violation("zero_before_hold", f"{_fmt(r)} out of OFFBOARD; before it: {detail}"))
    return out


def _finite_in_envelope(tl: _Timeline, limits: Limits) -> list[Violation]:
    out = []
    for s in tl.setpoints:
        vn, ve, vd = s["vel_ned_mps"]
        if not all(map(math.isfinite, (vn, ve, vd, s["yaw_rad"]))):
            out.append(Violation("finite_in_envelope", f"{_fmt(s)} yaw={s['yaw_rad']} is not finite"))
        elif math.hypot(vn, ve) > limits.max_h_speed_mps + 1e-3 or not (
            -limits.max_up_mps - 1e-3 <= vd <= limits.max_down_mps + 1e-3
        ):
            out.append(Violation("finite_in_envelope", f"{_fmt(s)} outside the envelope"))
    return out[:3]


def _only_stop_after_abort(tl: _Timeline, facts: RunFacts) -> list[Violation]:
    if facts.abort_t_s is None:
        return []
    out = []
    for r in tl.records:
        if r["t_s"] <= facts.abort_t_s + facts.grace_s:
            continue
        if r["event"] == "setpoint" and not _zero(r):
            out.append(Violation("only_stop_after_abort", f"{_fmt(r)} after ABORT at t={facts.abort_t_s:.2f}"))
        elif r["event"] == "command" and r.get("source") == "link":
            if r.get("command") != "DO_SET_MODE" or r.get("mode") != FlightMode.HOLD.value:
                out.append(Violation("only_stop_after_abort", f"{_fmt(r)} after ABORT at t={facts.abort_t_s:.2f}"))
    return out[:3]


def _watchdog(tl: _Timeline, limits: Limits) -> list[Violation]:
    out = []
    last_app: float | None = None
    for s in tl.setpoints:
        if s.get("origin") in ("app", "watchdog"):
            last_app = s["t_s"]
        elif not _zero(s) and last_app is not None and s["t_s"] - last_app > limits.watchdog_s + RESEND_S + EPS:
            out.append(Violation("watchdog", f"{_fmt(s)} re-sent {s['t_s'] - last_app:.2f} s after the app's last"))
    return out[:3]
