"""The ground station end to end: the real CLI flying the simulated pickup over MAVLink, a real mosquitto, the
operator's tools as the README documents them (``mosquitto_pub``, ``python -m app.gcs``). Real time.

With ``--mqtt`` the mission waits on the ground for ``start``; ``mosquitto_pub`` starts it; the broker is
killed and restarted mid-flight (the mission flies on, the link is back within 5 s and a command sent as the
broker comes back is not lost); ``abort`` over MQTT ends it in HOLD — checked on the simulator's side.
"""

from __future__ import annotations

import json
import signal
import subprocess
import sys
import threading
import time

import paho.mqtt.client as mqtt
import pytest

from tests.e2e.cliutil import ROOT, popen, read_jsonl, sim_modes, stop, wait_for, wait_for_state
from tests.gcs.mosquitto import Broker, find_tool

pytestmark = pytest.mark.e2e
VEHICLE = "e2e"
TOPICS = f"seapick/{VEHICLE}/v1"
ACTING = ("COMPONENT_ARM_DISARM", "NAV_TAKEOFF", "DO_SET_MODE", "NAV_LAND", "NAV_RETURN_TO_LAUNCH")


class Observer:
    """An operator's dashboard: every message under the vehicle's topics, reconnecting by itself."""

    def __init__(self, port: int) -> None:
        self.messages: list[tuple[float, str, bytes]] = []
        self._lock = threading.Lock()
        self.client = mqtt.Client(mqtt.CallbackAPIVersion.VERSION2, client_id="observer")
        self.client.reconnect_delay_set(0.1, 0.5)
        self.client.on_connect = lambda c, u, f, rc, p: c.subscribe(f"{TOPICS}/#", qos=1)
        self.client.on_message = self._on_message
        self.client.connect("127.0.0.1", port)
        self.client.loop_start()

    def _on_message(self, client, userdata, message) -> None:
        with self._lock:
            self.messages.append((time.monotonic(), message.topic, message.payload))

    def last(self, topic: str, after_s: float = 0.0) -> dict | None:
        with self._lock:
            found = [p for t, top, p in self.messages if top == f"{TOPICS}/{topic}" and t >= after_s]
        return json.loads(found[-1]) if found else None

    def acks(self) -> list[dict]:
        with self._lock:
            return [json.loads(p) for _, top, p in self.messages if top == f"{TOPICS}/cmd/ack"]

    def events(self) -> list[dict]:
        with self._lock:
            return [json.loads(p) for _, top, p in self.messages if top == f"{TOPICS}/events"]

    def close(self) -> None:
        self.client.loop_stop()
        self.client.disconnect()


def gcs(port: int, *args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "app.gcs", *args, "--broker", f"mqtt://127.0.0.1:{port}", "--vehicle-id", VEHICLE],
        cwd=ROOT, capture_output=True, text=True, timeout=60,
    )  # fmt: skip


def test_started_over_mqtt_survives_a_broker_restart_and_aborts_into_hold_on_an_operators_command(tmp_path):
    broker = Broker(tmp_path / "broker", persistence=True)
    broker.directory.mkdir()
    broker.start()
    run_dir = tmp_path / "run"
    app = popen(
        ["-m", "app.main", "--mission", "pickup.yaml", "--sim", "--seed", "1", "--run-dir", str(run_dir),
         "--pilot-port", "0", "--mqtt", broker.url, "--vehicle-id", VEHICLE],
        tmp_path / "app.log",
    )  # fmt: skip
    observer = Observer(broker.port)
    log = lambda: (tmp_path / "app.log").read_text()[-3000:]  # noqa: E731
    try:
        waiting = wait_for(lambda: (observer.last("state") or {}).get("mission_state") == "WAIT_FOR_START", 60.0)
        assert waiting, log()
        assert observer.last("online") is True
        time.sleep(5.0)  # a mission that does not wait would be taking off by now
        sim_log = read_jsonl(run_dir / "sim_state.jsonl")
        acting = [r for r in sim_log if r.get("event") == "command" and r.get("command") in ACTING]
        assert not acting and not any(r.get("armed") for r in sim_log), acting
        assert observer.last("state")["mission_state"] == "WAIT_FOR_START" and not observer.last("state")["armed"]

        # exactly as the README has it
        pub = [find_tool("mosquitto_pub"), "-h", "127.0.0.1", "-p", str(broker.port), "-q", "1"]
        subprocess.run([*pub, "-t", f"{TOPICS}/cmd", "-m", '{"cmd":"start","id":"1"}'], check=True, timeout=10)
        assert wait_for(lambda: any(a["id"] == "1" for a in observer.acks()), 10.0)
        assert next(a for a in observer.acks() if a["id"] == "1") == {
            "id": "1", "cmd": "start", "accepted": True, "reason": None,
        }  # fmt: skip
        assert wait_for_state(run_dir / "events.jsonl", "GOTO_SEARCH", 90.0), log()
        telemetry = wait_for(lambda: observer.last("telemetry"), 5.0)
        assert telemetry and telemetry["position_ned_m"][2] < -5.0, telemetry  # flying, up at the search height
        assert 14.0 < telemetry["battery"]["voltage_v"] < 17.0 and 0.5 < telemetry["battery"]["remaining_frac"] <= 1
        kinds = [e["kind"] for e in observer.events()]
        assert kinds.count("state_changed") >= 3 and "start_given" in kinds, kinds
        calibration = wait_for(lambda: [e for e in observer.events() if e["kind"] == "radar_calibration"], 5.0)
        assert calibration and calibration[0]["fields"]["result"].startswith("ok"), calibration

        # the broker dies mid-flight and comes back 3 s later; a hold sent as it comes back is not lost
        broker.kill()
        time.sleep(3.0)
        broker.start()
        t_back = time.monotonic()
        hold = gcs(broker.port, "hold", "--id", "h1", "--timeout", "10")
        assert hold.returncode == 0, (hold.stdout, hold.stderr)
        back_s = wait_for(lambda: observer.last("online", after_s=t_back) is True and time.monotonic(), 10.0)
        assert back_s, "the link did not announce itself again"
        print(f"link back {back_s - t_back:.2f} s after the broker; hold acked {json.loads(hold.stdout)}")
        assert back_s - t_back < 5.0
        assert wait_for_state(run_dir / "events.jsonl", "HOLD", 10.0)
        assert wait_for(lambda: sim_modes(run_dir) and sim_modes(run_dir)[-1]["mode"] == "HOLD", 10.0)
        assert gcs(broker.port, "resume", "--id", "r1").returncode == 0

        time.sleep(2.0)
        abort = gcs(broker.port, "abort", "--id", "a1")
        assert abort.returncode == 0, (abort.stdout, abort.stderr)
        assert json.loads(abort.stdout)["accepted"] is True
        code = app.wait(timeout=60)
        final = wait_for(lambda: (observer.last("state") or {}).get("outcome"), 10.0)
    finally:
        stop(app, signal.SIGKILL)
        observer.close()
        broker.stop()
    s = json.loads((run_dir / "summary.json").read_text())
    print(s["states_visited"], s["gcs"])
    assert code == 1 and s["outcome"] == "aborted" and s["final_state"] == "ABORT"
    assert final == "aborted" and observer.last("state")["mission_state"] == "ABORT"
    # the vehicle's side: it ended in HOLD
    assert sim_modes(run_dir)[-1]["mode"] == "HOLD"
    visited = s["states_visited"]
    assert visited[:4] == ["WAIT_FOR_START", "TAKEOFF", "CALIBRATE_RADAR", "GOTO_SEARCH"]
    assert "HOLD" in visited and visited[-1] == "ABORT"  # flew on through the outage; no abort until asked
    assert s["gcs"]["reconnects"] >= 1 and s["gcs"]["accepted"] == 4 and s["gcs"]["malformed"] == 0
