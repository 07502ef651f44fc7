"""The safety rules catch what they are for: each one on a vehicle log that breaks it, and none on a clean one."""

from __future__ import annotations

from sim.safety_rules import Limits, RunFacts, check

LIMITS = Limits(max_h_speed_mps=3.0, max_up_mps=1.0, max_down_mps=1.0, zero_s=0.5, watchdog_s=0.2)


def facts(**kw):
    base = dict(
        outcome="aborted",
        reason="abort requested (SIGINT)",
        expected_outcomes=frozenset({"aborted"}),
        abort_t_s=10.0,
        log_lines=7,
        log_records=7,
        grace_s=0.06,
        end_t_s=20.0,
    )
    return RunFacts(**(base | kw))


def sp(t, v=(0.0, 0.0, 0.0), yaw=0.0, origin="app"):
    return {"t_s": t, "event": "setpoint", "vel_ned_mps": list(v), "yaw_rad": yaw, "origin": origin}


def mode(t, m, reason="command"):
    return {"t_s": t, "event": "mode", "mode": m, "reason": reason}


def cmd(t, m="HOLD", command="DO_SET_MODE", source="link"):
    return {"t_s": t, "event": "command", "command": command, "mode": m, "result": "ACCEPTED", "source": source}


def clean_abort():
    """Tracking at 1 m/s, ABORT at 10 s: 0.5 s of zeros at 50 Hz, then HOLD; zeros re-sent after."""
    recs = [{"t_s": 0.0, "event": "armed", "armed": True}, mode(1.0, "OFFBOARD")]
    recs += [sp(1.0 + 0.02 * i, (1.0, 0.0, 0.0)) for i in range(450)]
    recs += [sp(10.02 + 0.02 * i) for i in range(25)]
    recs += [cmd(10.52), mode(10.52, "HOLD")]
    recs += [sp(10.57 + 0.05 * i, origin="resend") for i in range(10)]
    return recs


def rules(records, **kw):
    return sorted({v.rule for v in check(records, facts(**kw), LIMITS)})


def test_a_clean_abort_breaks_no_rule():
    assert rules(clean_abort()) == []


def test_hold_straight_after_a_moving_setpoint_breaks_zero_before_hold_and_only_stop_after_abort():
    recs = [r for r in clean_abort() if not (r["event"] == "setpoint" and 10.0 < r["t_s"] < 10.52)]
    recs.insert(-11, sp(10.4, (1.0, 0.0, 0.0)))
    assert rules(recs) == ["only_stop_after_abort", "zero_before_hold"]


def test_a_command_after_the_pilot_switch_is_caught():
    recs = [*clean_abort()[:200], mode(5.0, "POSCTL", reason="pilot"), cmd(6.0, m="OFFBOARD")]
    recs.sort(key=lambda r: r["t_s"])
    assert "no_command_after_takeover" in rules(recs, outcome="pilot", expected_outcomes=frozenset({"pilot"}))


def test_non_finite_and_too_fast_setpoints_are_caught():
    recs = clean_abort()
    recs[5] = sp(recs[5]["t_s"], (1.0, 0.0, 0.0), yaw=float("nan"))
    assert rules(recs) == ["finite_in_envelope"]
    recs = clean_abort()
    recs[5] = sp(recs[5]["t_s"], (3.5, 0.0, 0.0))
    assert rules(recs) == ["finite_in_envelope"]


def test_a_non_zero_setpoint_resent_past_the_watchdog_is_caught():
    recs = clean_abort()[:100] + [sp(2.98 + 0.05 * i, (1.0, 0.0, 0.0), origin="resend") for i in range(1, 7)]
    assert "watchdog" in rules(recs, abort_t_s=None, end_t_s=3.5)


def test_left_flying_on_a_resent_velocity_and_wrong_outcome_and_lost_records_are_caught():
    recs = clean_abort()[:300]  # still in OFFBOARD, still re-sent at 1 m/s
    got = rules(recs, abort_t_s=None, outcome="completed", end_t_s=recs[-1]["t_s"], log_lines=6)
    assert got == ["no_lost_log_record", "safe_end"]
