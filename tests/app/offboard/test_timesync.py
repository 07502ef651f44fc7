"""Autopilot sample times on the loop clock: the estimator alone, then the adapter on a real MAVLink link."""

from __future__ import annotations

import asyncio
import json
import random
import time

import numpy as np

from app.clock import LoopClock
from app.eventlog import EventLog
from app.messages import AttitudeEuler, PositionVelocityNed
from app.offboard.timesync import AUTOPILOT, RECEIPT, RemoteClock
from app.settings import ConnectionSettings, TelemetrySettings
from sim.autopilot import SimAutopilot, SimConfig
from sim.estimator import PERFECT
from sim.state_log import read_state_log
from sim.wind import WindConfig
from tests.sim.conftest import eventually, free_udp_port

OFFSET_S = 1234.5  # loop clock minus autopilot clock


def delivered(rng: random.Random, n: int, period_s: float = 0.02) -> list[tuple[float, float]]:
    """(remote_s, received_s) for samples every ``period_s``: small jitter, and stalls of the receiver
    (every 0.5 s the app is busy for 80-150 ms and gets everything queued at once at the end)."""
    out = []
    stall_end_s = -1.0
    for k in range(n):
        remote_s = k * period_s
        if k % 25 == 0:
            stall_end_s = remote_s + rng.uniform(0.08, 0.15)
        received_s = remote_s + OFFSET_S + 0.0003 + rng.expovariate(1 / 0.002)
        if remote_s < stall_end_s:
            received_s = max(received_s, stall_end_s + OFFSET_S)
        out.append((remote_s, received_s))
    return out


def test_stamps_are_the_sample_times_despite_receiver_stalls():
    clock = RemoteClock()
    errors, late = [], []
    for remote_s, received_s in delivered(random.Random(3), 5000):
        t_s = clock.stamp(remote_s, received_s)
        assert t_s <= received_s
        if remote_s < 7.4:
            assert clock.mode == RECEIPT and t_s == received_s  # the clock's rate is not known yet
        if remote_s >= 7.5:
            assert clock.mode == AUTOPILOT
            errors.append(abs(t_s - (remote_s + OFFSET_S)))
            late.append(received_s - (remote_s + OFFSET_S))
    assert max(errors) < 0.002  # the window's fastest packet: ~0.3 ms transport
    assert max(late) > 0.08  # the stalls were there: receipt stamps would have been 80+ ms late
    stats = clock.summary("position")
    assert stats["position_clock"] == "autopilot"
    assert stats["position_latency_max_s"] is not None and stats["position_latency_max_s"] > 0.08
    assert stats["position_latency_p50_s"] is not None and stats["position_latency_p50_s"] < 0.01


def crystal(rate: float, seconds: float, seed: int) -> list[tuple[float, float, float]]:
    """(true_s, remote_s, received_s) at 50 Hz for an autopilot clock running at ``rate`` × real time."""
    rng = random.Random(seed)
    out = []
    for k in range(int(seconds * 50)):
        true_s = k * 0.02
        out.append((true_s, 100.0 + true_s * rate, true_s + OFFSET_S + 0.0003 + rng.expovariate(1 / 0.002)))
    return out


def test_drifting_autopilot_crystal_is_followed():
    clock = RemoteClock(window_s=10.0)
    worst = 0.0
    for true_s, remote_s, received_s in crystal(1 + 150e-6, 1200.0, 5):  # 20 minutes, 150 ppm fast
        t_s = clock.stamp(remote_s, received_s)
        if true_s > 10.0:
            worst = max(worst, abs(t_s - (true_s + OFFSET_S)))
    assert clock.mode == AUTOPILOT and clock.rate is not None and abs(clock.rate + 150e-6) < 30e-6
    assert worst < 0.001  # the window's minimum alone would lag this drift by up to 1.5 ms


def test_a_clock_not_in_real_time_keeps_receipt_stamps():
    """PX4 SITL in lockstep at a real-time factor of 0.9: its time_boot_ms cannot be mapped."""
    clock = RemoteClock()
    for _true_s, remote_s, received_s in crystal(0.9, 60.0, 6):
        assert clock.stamp(remote_s, received_s) == received_s
    assert clock.mode == RECEIPT and clock.rate is not None and abs(clock.rate - 0.1 / 0.9) < 0.01
    assert clock.summary("position")["position_clock"] == "receipt"


def test_autopilot_reboot_starts_afresh():
    clock = RemoteClock()
    for k in range(1000):
        clock.stamp(1000.0 + k * 0.02, OFFSET_S + 1000.0 + k * 0.02 + 0.001)
    assert clock.mode == AUTOPILOT
    # rebooted: time_boot_ms restarts at 0, ten seconds of loop time later
    t_s = clock.stamp(0.5, OFFSET_S + 1030.0 + 0.001)
    assert clock.resets == 1
    assert clock.mode == RECEIPT and t_s == OFFSET_S + 1030.0 + 0.001  # not 1019.5 s earlier (the old offset)
    for k in range(1, 500):
        t_s = clock.stamp(0.5 + k * 0.02, OFFSET_S + 1030.0 + k * 0.02 + 0.001)
    assert clock.mode == AUTOPILOT and abs(t_s - (OFFSET_S + 1030.0 + 499 * 0.02 + 0.001)) < 1e-6  # the new offset


async def test_adapter_positions_agree_with_truth_at_their_stamps_while_the_loop_stalls(tmp_path):
    """Real MAVSDK on real UDP: climbing at ~1.5 m/s, the app's loop blocked 150 ms every half second.

    Each position sample is compared with the simulator's truth at the sample's stamp (the sim's clock is
    time.monotonic, as is the asyncio loop's). Stamped when the loop reads them, samples queued during a
    stall would be placed up to 150 ms late — over 10 cm at this climb rate.
    """
    from app.offboard.mavsdk_vehicle import MavsdkVehicle

    port = free_udp_port()
    truth_log = tmp_path / "truth.jsonl"
    config = SimConfig(  # a perfect estimate: what the autopilot reports is the truth the log holds
        target=("127.0.0.1", port), pilot_port=None, wind=WindConfig.off(), state_log=str(truth_log), estimator=PERFECT
    )
    sim = SimAutopilot(config)
    clock = LoopClock()
    seen: list[tuple[float, float, float]] = []  # every position sample: (stamp, read by the loop, down)

    def record(sample: PositionVelocityNed | AttitudeEuler, received_s: float) -> None:
        if isinstance(sample, PositionVelocityNed):
            seen.append((sample.t_s, clock.now_s(), sample.pos_ned_m[2]))

    def busy(dt_s: float) -> None:
        """The event loop is busy elsewhere (a slow callback): nothing of ours runs meanwhile."""
        time.sleep(dt_s)

    try:
        sim.start()
        async with MavsdkVehicle.connect(
            f"udpin://0.0.0.0:{port}", clock, EventLog(None), ConnectionSettings(), TelemetrySettings()
        ) as vehicle:
            vehicle.add_sample_listener(record)
            streams = asyncio.create_task(vehicle.run())
            try:
                await vehicle.wait_ready(20.0)

                async def on_autopilot_time() -> bool:
                    return vehicle.link_stats()["position_clock"] == "autopilot"

                await eventually(on_autopilot_time, 20.0)  # its rate is measured over the first 7.5 s
                await vehicle.arm()
                await vehicle.takeoff(8.0)
                t_end_s = clock.now_s() + 60.0
                while clock.now_s() < t_end_s and sum(1 for s in seen if s[2] < -2.0) < 150:
                    await asyncio.sleep(0.5)
                    busy(0.15)
                stats = vehicle.link_stats()
            finally:
                streams.cancel()
    finally:
        sim.stop()
    truth = [r for r in read_state_log(truth_log) if r["event"] == "truth"]
    t_truth = np.array([r["t_s"] for r in truth]) + sim.boot_monotonic_s
    d_truth = np.array([r["pos_ned_m"][2] for r in truth])
    climbing = [s for s in seen if -7.0 < s[2] < -1.0 and t_truth[0] < s[1] < t_truth[-1]]
    assert len(climbing) > 100
    err_stamp = [abs(d - np.interp(t, t_truth, d_truth)) for t, _, d in climbing]
    err_read = [abs(d - np.interp(r, t_truth, d_truth)) for _, r, d in climbing]
    assert max(err_stamp) < 0.02
    assert max(err_read) > 0.10  # the stalls were real: stamped when read, samples are far off
    # Received in MAVSDK's thread, not when the loop got to them: the stalls do not show as link latency.
    print(f"position latency p95 {stats['position_latency_p95_s']} s, max {stats['position_latency_max_s']} s")


async def test_a_mode_switch_during_a_loop_stall_is_stamped_when_it_arrived_not_when_read(tmp_path):
    """The pilot switches while the app's loop is blocked for 0.8 s: the first sample showing the new mode
    carries the time MAVSDK received it (within a CURRENT_MODE period of the switch), not the end of the stall
    (stamped when read, the whole backlog would look fresh)."""
    import threading

    from app.messages import FlightMode
    from app.offboard.mavsdk_vehicle import MavsdkVehicle
    from sim import pilot

    port = free_udp_port()
    sim = SimAutopilot(SimConfig(target=("127.0.0.1", port), pilot_port=0, wind=WindConfig.off()))
    clock = LoopClock()
    events = EventLog(tmp_path / "events.jsonl")
    switched: list[float] = []

    def pilot_switch() -> None:
        time.sleep(0.2)
        assert sim.pilot_address is not None
        switched.append(time.monotonic())
        pilot.set_mode("POSCTL", "127.0.0.1", sim.pilot_address[1], 5.0)

    try:
        sim.start()
        async with MavsdkVehicle.connect(
            f"udpin://0.0.0.0:{port}", clock, events, ConnectionSettings(), TelemetrySettings()
        ) as vehicle:
            streams = asyncio.create_task(vehicle.run())
            try:
                await vehicle.wait_ready(20.0)
                await eventually(lambda: vehicle.telemetry().mode() is FlightMode.HOLD, 10.0)
                await asyncio.sleep(1.0)  # CURRENT_MODE requested and flowing
                threading.Thread(target=pilot_switch, daemon=True).start()
                time.sleep(0.8)  # noqa: ASYNC251 — the loop is blocked on purpose
                unblocked = clock.now_s()
                await asyncio.sleep(0.05)
                tel = vehicle.telemetry()
            finally:
                streams.cancel()
    finally:
        sim.stop()
        events.close()
    assert tel.flight_mode is not None and tel.flight_mode.value is FlightMode.POSCTL
    lines = [json.loads(x) for x in (tmp_path / "events.jsonl").read_text().splitlines()]
    first = next(e for e in lines if e.get("event") == "flight_mode" and e["mode"] == "POSCTL")
    after_switch_s, read_after_s = first["t_s"] - switched[0], unblocked - switched[0]
    print(
        f"POSCTL stamped {after_switch_s * 1000:.0f} ms after the switch; the loop was free {read_after_s:.2f} s later"
    )
    assert 0.0 <= after_switch_s < read_after_s - 0.2  # received during the stall, and stamped so
    assert tel.heartbeat_t_s is not None and tel.heartbeat_t_s <= unblocked + 0.05
