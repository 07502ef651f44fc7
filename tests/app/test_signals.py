"""``handle_signals_in_thread``: what a signal should do runs in a thread of its own, never in the handler — a
handler that took a lock the interrupted main thread holds (``Event.set`` in a handler nested in itself) waited
forever: a simulator whose app was killed hung so (the parent-death signal comes once per thread of the app)."""

from __future__ import annotations

import json
import subprocess
import sys
import textwrap
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]

# Its own process: the handlers and the thread would otherwise stay in pytest's.
SCRIPT = textwrap.dedent(
    """
    import json, signal, threading, time
    from app.cli import handle_signals_in_thread

    lock = threading.Lock()
    done = threading.Event()
    ran_in = []

    def work():
        with lock:
            ran_in.append(threading.current_thread().name)
        done.set()

    handle_signals_in_thread({signal.SIGTERM: work})
    with lock:  # the signal comes while the main thread holds the lock the work needs
        signal.raise_signal(signal.SIGTERM)  # the Python handler has run when this returns
        time.sleep(0.2)
        waited = not done.is_set()
    finished = done.wait(10.0)
    print(json.dumps({"waited_for_the_lock": waited, "finished": finished, "ran_in": ran_in}))
    """
)


def test_a_signal_while_the_main_thread_holds_a_lock_runs_its_work_after_the_lock_is_free():
    # A handler that did the work itself would wait for the lock its own thread holds: the timeout fails the test.
    done = subprocess.run([sys.executable, "-c", SCRIPT], cwd=ROOT, capture_output=True, text=True, timeout=30)
    assert done.returncode == 0, done.stderr
    assert json.loads(done.stdout) == {"waited_for_the_lock": True, "finished": True, "ran_in": ["signals"]}
