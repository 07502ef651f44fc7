"""The event log writes on its own thread: nothing lost on a clean exit, state records on disk at once."""

from __future__ import annotations

import json
import threading
import time

from app.eventlog import EventLog


def test_records_from_several_threads_all_reach_the_file_even_through_a_tiny_queue(tmp_path):
    path = tmp_path / "events.jsonl"
    log = EventLog(path, queue_size=8)  # writers block for room instead of dropping

    def writer(k):
        for i in range(2000):
            log.write(float(i), "setpoint", thread=k, i=i, vel=[float("nan"), 1.0, 2.0])

    threads = [threading.Thread(target=writer, args=(k,)) for k in range(3)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    log.close()
    lines = [json.loads(x) for x in path.read_text().splitlines()]
    assert len(lines) == 6000 == log.total() == log.written
    for k in range(3):
        assert [r["i"] for r in lines if r["thread"] == k] == list(range(2000))  # in order per thread
    assert lines[0]["vel"] == [None, 1.0, 2.0]  # NaN becomes null, valid JSON


def test_a_state_record_is_on_disk_before_close(tmp_path):
    path = tmp_path / "events.jsonl"
    log = EventLog(path)
    for i in range(100):
        log.write(float(i), "setpoint", i=i)
    log.write(100.0, "state", to="ABORT", reason="SIGINT")
    deadline = time.monotonic() + 10.0  # generous: the writer thread on a loaded machine
    while time.monotonic() < deadline and "ABORT" not in path.read_text():
        time.sleep(0.01)
    text = path.read_text()
    assert '"to":"ABORT"' in text and len(text.splitlines()) == 101
    log.close()
    log.close()  # idempotent
