"""``run.mcap`` and ``--foxglove``: a run's records as Foxglove channels, read back with the ``mcap`` reader and
received from the live server over a plain WebSocket client."""

from __future__ import annotations

import base64
import json
import math
import socket
import struct
import subprocess
import sys
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import pytest
from mcap.records import Schema
from mcap_protobuf.decoder import DecoderFactory
from websockets.sync.client import ClientConnection, connect

from app.errors import ConfigError
from app.estimators.rotations import quat_from_euler_zyx
from app.eventlog import EventLog
from app.foxglove_live import LiveServer
from app.foxglove_log import ELLIPSE_SIGMAS, FIX_LIFETIME_S, MCAP_NAME, time_ns, write_mcap
from sim.evaluate_pickup import run_pickup
from sim.pickup_scenarios import sample_scenarios
from tests.mcaputil import check_run_mcap, position, read_mcap

ROOT = Path(__file__).resolve().parents[2]
BOOT_S = 1000.0  # the simulator's clock starts this far into the app's
PICKUP = {
    "state": "TRACK", "vehicle_ne_m": [3.0, 4.0], "vehicle_down_m": -5.0, "vehicle_rpy_rad": [0.1, -0.2, 1.5],
    "estimate_ne_m": [3.5, 4.5], "estimate_down_m": 0.25, "estimate_sigma_ne_m": [0.3, 0.1], "estimate_rho_ne": 0.0,
    "height_above_sea_m": 5.2, "fix_age_s": 0.1,
}  # fmt: skip


@pytest.fixture(scope="module")
def real_run(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """One quick evaluation run (sea state 1, a buoy on PX4: picked up in ~100 s of virtual time, ~10 s of CPU)."""
    run_dir = tmp_path_factory.mktemp("run")
    result = run_pickup(sample_scenarios(23, 2, 1)[0], "seapick", 0, str(run_dir))
    assert result["outcome"] == "picked_up", result
    return run_dir


def test_a_real_runs_mcap_reads_back_channel_by_channel(real_run):
    """Every pickup topic with its schema, times in order and within the run, a mid-run pose to the digit."""
    rec = check_run_mcap(real_run)
    sim = [json.loads(x) for x in (real_run / "sim_state.jsonl").read_text().splitlines()]
    truth = [r for r in sim if r["event"] == "object"][100]
    t_ns, pose = rec.messages["/object/truth"][100]
    assert t_ns == time_ns(truth["t_s"]) and position(pose) == truth["pos_ned_m"]
    states = [json.loads(x) for x in (real_run / "events.jsonl").read_text().splitlines()]
    states = [r for r in states if r["kind"] == "state"]
    assert [m["state"] for _, m in rec.messages["/mission/state"]] == [r["to"] for r in states]
    assert rec.messages["/mission/state"][-1][1]["state"] == "DONE"


def test_writing_again_replaces_the_file_and_a_failed_write_leaves_none(real_run, tmp_path):
    """``write_mcap`` overwrites an old ``run.mcap``; a run dir without an event log gets no file, not half of one."""
    first = (real_run / MCAP_NAME).read_bytes()
    assert write_mcap(real_run).read_bytes() == first  # the same records make the same file
    (tmp_path / MCAP_NAME).write_bytes(b"stale")
    with pytest.raises(FileNotFoundError):
        write_mcap(tmp_path)
    assert sorted(p.name for p in tmp_path.iterdir()) == []


def write_records(run_dir: Path) -> bytes:
    """A small run: the app's records through a real EventLog, the simulator's truth on a clock BOOT_S behind."""
    jpeg = cv2.imencode(".jpg", np.full((12, 16, 3), 200, np.uint8))[1].tobytes()
    (run_dir / "camera").mkdir()
    (run_dir / "camera" / "000001.jpg").write_bytes(jpeg)
    events = EventLog(run_dir / "events.jsonl")
    events.write(BOOT_S + 1.0, "state", **{"from": None, "to": "TRACK", "reason": "start"})
    events.write(BOOT_S + 1.0, "command", name="arm", result="refused", authority="pilot")
    events.write(BOOT_S + 1.1, "fix", ne_m=[3.4, 4.6], result="fused")
    events.write(BOOT_S + 1.15, "fix", ne_m=[3.3, 4.4], result="filter_outlier")
    events.write(BOOT_S + 1.2, "pickup", **PICKUP)
    events.write(BOOT_S + 1.2, "pickup", **(PICKUP | {"estimate_sigma_ne_m": [0.2, 0.2], "estimate_rho_ne": 0.5}))
    events.write(BOOT_S + 1.22, "setpoint", decision="guide", source="track", vel=[0.1, 0.2, 0.3], limits=["speed"])
    events.write(BOOT_S + 1.25, "radar_profile", range_start_m=0.2, range_step_m=0.05, amplitude=[0.0, 1.5, 0.25])
    events.write(BOOT_S + 1.3, "camera", jpeg="camera/000001.jpg")
    events.write(BOOT_S + 1.4, "pickup", state="TRACK")  # a record of a shape the mapping does not know
    events.close()
    sim = [
        {"event": "start", "t_s": 0.0, "boot_monotonic_s": BOOT_S},
        {"event": "truth", "t_s": 1.05, "pos_ned_m": [3.0, 4.1, -5.0], "att_rad": [0.0, 0.0, 0.5]},
        {"event": "grab", "t_s": 1.3, "error_m": 0.04, "caught": True, "slipped": False},
    ]
    (run_dir / "sim_state.jsonl").write_text("".join(json.dumps(r) + "\n" for r in sim))
    return jpeg


def test_each_record_kind_lands_on_its_channel(tmp_path):
    """Frames, attitude, the 2σ ellipse, fixes by verdict, JSON channels as logged, the camera's JPEG, warnings,
    the simulator's truth on the app's clock, and an unknown record shape skipped and counted."""
    jpeg = write_records(tmp_path)
    rec = read_mcap(write_mcap(tmp_path))
    assert rec.metadata["seapick"] == {"run_dir": tmp_path.name, "records": "12", "skipped": "1"}
    t_ns = time_ns(BOOT_S + 1.2)

    world, body = rec.messages["/tf"][0][1].transforms
    assert (world.parent_frame_id, world.child_frame_id, body.parent_frame_id, body.child_frame_id) == (
        "world", "ned", "ned", "vehicle"
    )  # fmt: skip
    assert (world.rotation.x, world.rotation.w) == (1.0, 0.0)  # z down → z up: a half turn about north
    w, x, y, z = quat_from_euler_zyx(0.1, -0.2, 1.5)
    q = body.rotation
    assert [body.translation.x, body.translation.y, body.translation.z] == [3.0, 4.0, -5.0]
    assert [q.x, q.y, q.z, q.w] == pytest.approx([x, y, z, w])

    (t0, plain), (_, tilted) = rec.messages["/object/covariance"]
    sphere = plain.entities[0].spheres[0]
    assert t0 == t_ns and position(sphere) == [3.5, 4.5, 0.25]
    assert [sphere.size.x, sphere.size.y] == pytest.approx([2 * ELLIPSE_SIGMAS * 0.3, 2 * ELLIPSE_SIGMAS * 0.1])
    assert sphere.pose.orientation.z == pytest.approx(0.0)  # the major axis along north
    sphere = tilted.entities[0].spheres[0]  # σ 0.2 both, ρ 0.5: axes √(0.04 ± 0.02) at 45°
    assert [sphere.size.x, sphere.size.y] == pytest.approx([2 * ELLIPSE_SIGMAS * math.sqrt(v) for v in (0.06, 0.02)])
    assert sphere.pose.orientation.z == pytest.approx(math.sin(math.pi / 8))

    fused, outlier = (m.entities[0] for _, m in rec.messages["/detections"])
    assert position(fused.spheres[0]) == [3.4, 4.6, 0.0]  # no estimate yet: drawn at home's level
    assert (fused.spheres[0].color.g, outlier.spheres[0].color.r) == (pytest.approx(0.8), pytest.approx(0.9))
    assert fused.lifetime.seconds == FIX_LIFETIME_S and fused.id != outlier.id

    assert [m for _, m in rec.messages["/setpoint"]] == [
        {"decision": "guide", "source": "track", "vel": [0.1, 0.2, 0.3], "limits": ["speed"]}
    ]
    assert rec.messages["/radar/profile"] == [
        (time_ns(BOOT_S + 1.25), {"range_start_m": 0.2, "range_step_m": 0.05, "amplitude": [0.0, 1.5, 0.25]})
    ]
    assert [m for _, m in rec.messages["/radar/height"]] == [{"height_above_sea_m": 5.2}] * 2
    image = rec.messages["/camera/image"][0][1]
    assert (image.format, image.data) == ("jpeg", jpeg)

    logs = {m.name: m for _, m in rec.messages["/log"]}
    assert logs["state"].message == "→ TRACK: start"
    assert logs["command"].level == 3 and "result=refused" in logs["command"].message  # WARNING
    assert "caught" in logs["sim"].message and rec.messages["/log"][-1][0] == time_ns(BOOT_S + 1.3)
    t_truth, truth = rec.messages["/vehicle/truth"][0]
    assert t_truth == time_ns(BOOT_S + 1.05) and position(truth) == [3.0, 4.1, -5.0]


# ---- live --------------------------------------------------------------------------------------------------------


def receive_json(ws: ClientConnection, op: str) -> dict[str, Any]:
    while True:
        msg = ws.recv(timeout=5)
        if isinstance(msg, str) and json.loads(msg)["op"] == op:
            return json.loads(msg)


def test_the_live_server_advertises_the_channels_and_sends_records_as_they_are_logged(tmp_path):
    """A WebSocket client (Foxglove's protocol) sees the channels advertised when the run first logs on them and
    receives a subscribed pose stamped with its record's time; a record of unknown shape is skipped, not fatal."""
    events = EventLog(tmp_path / "events.jsonl")
    live = LiveServer.start(events, port=0)
    try:
        with connect(live.url, subprotocols=["foxglove.sdk.v1"], open_timeout=5) as ws:
            assert receive_json(ws, "serverInfo")["name"] == "seapick"
            events.write(10.0, "pickup", state="TRACK")  # unknown shape: nothing to advertise
            events.write(10.2, "pickup", **PICKUP)
            topics: dict[str, Any] = {}
            while not {"/vehicle/pose", "/object/covariance", "/radar/height"} <= set(topics):
                topics |= {c["topic"]: c for c in receive_json(ws, "advertise")["channels"]}
            pose = topics["/vehicle/pose"]
            assert (pose["encoding"], pose["schemaName"]) == ("protobuf", "foxglove.PoseInFrame")
            ws.send(json.dumps({"op": "subscribe", "subscriptions": [{"id": 7, "channelId": pose["id"]}]}))
            moved = PICKUP | {"vehicle_ne_m": [30.0, 40.0]}
            for k in range(20):  # until the subscription is in place: then every pose arrives
                events.write(11.0 + k, "pickup", **moved)
                try:
                    frame = ws.recv(timeout=0.5)
                    break
                except TimeoutError:
                    continue
            else:
                pytest.fail("no pose reached the subscribed client")
            opcode, subscription, log_time = struct.unpack_from("<BIQ", frame)
            schema = Schema(id=1, name=pose["schemaName"], encoding="protobuf", data=base64.b64decode(pose["schema"]))
            decoded = DecoderFactory().decoder_for("protobuf", schema)(frame[13:])
            assert (opcode, subscription, log_time) == (1, 7, time_ns(11.0 + k))
            assert position(decoded) == [30.0, 40.0, -5.0]
    finally:
        events.close()
        live.stop()
    assert live.skipped == 1 and live.dropped == 0


def test_a_port_in_use_is_refused_before_anything_flies(tmp_path):
    """The server's port taken: ``LiveServer.start`` raises ConfigError, and the CLI says so in one line, exit 2."""
    with socket.socket() as busy:
        busy.bind(("127.0.0.1", 0))
        busy.listen()
        port = busy.getsockname()[1]
        with pytest.raises(ConfigError, match=f"--foxglove-port: cannot serve on 127.0.0.1:{port}"):
            LiveServer.start(EventLog(None), port)
        proc = subprocess.run(
            [sys.executable, "-m", "app.main", "--mission", "circle.yaml", "--run-dir", str(tmp_path / "run"),
             "--foxglove", "--foxglove-port", str(port)],
            cwd=ROOT, capture_output=True, text=True, timeout=60,
        )  # fmt: skip
    lines = proc.stderr.strip().splitlines()
    assert proc.returncode == 2 and len(lines) == 1 and "--foxglove-port" in lines[0], proc.stderr
