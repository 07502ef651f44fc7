"""``--foxglove``: the run's channels served live to the Foxglove app on a local WebSocket, as they are logged.

The event log hands each record to ``LiveServer._on_record`` on the thread that wrote it — for most records the
event loop's, in the middle of the 50 Hz setpoint loop. So that costs one put on a bounded latest-wins queue
(``app.queues.LatestQueue``: full, it drops the oldest record and counts it); a thread of its own (``foxglove.live``)
takes the records, maps them onto channels (``app.foxglove_log.RunChannels``, the same mapping ``run.mcap`` gets) and
hands them to the SDK's server, which sends them to every connected client. A record the mapping cannot take is
counted (``skipped``), never raised into the writer. The simulator's truth is another process's file: it is in
``run.mcap``, not here.
"""

from __future__ import annotations

import threading
from pathlib import Path
from typing import Any

import foxglove

from app.errors import ConfigError
from app.eventlog import EventLog
from app.foxglove_log import EVENT_KINDS, RunChannels
from app.queues import LatestQueue

HOST = "127.0.0.1"
DEFAULT_PORT = 8765  # Foxglove's own default for a WebSocket connection
QUEUE_SIZE = 2_000  # records: 40 s of 50 Hz setpoints while the thread is starved


class LiveServer:
    """A Foxglove WebSocket server on ``HOST``, fed from one event log; ``start`` it, ``stop`` it when the run ends."""

    def __init__(self, server: foxglove.websocket.WebSocketServer, channels: RunChannels) -> None:
        self.server = server
        self.port = server.port
        self.channels = channels
        self._queue: LatestQueue[dict[str, Any]] = LatestQueue(QUEUE_SIZE)
        self._wake = threading.Event()
        self._stopping = False
        self._thread = threading.Thread(target=self._forward, name="foxglove.live", daemon=True)

    @classmethod
    def start(cls, events: EventLog, port: int = DEFAULT_PORT, run_dir: Path | None = None) -> LiveServer:
        """Serve on ``ws://127.0.0.1:port`` (0: a free port, see ``.port``); raises ``ConfigError`` when the port
        cannot be had."""
        context = foxglove.Context()
        try:
            server = foxglove.start_server(name="seapick", host=HOST, port=port, context=context)
        except Exception as e:  # the SDK raises its own RuntimeError subclasses for a port in use
            raise ConfigError("--foxglove-port", "", f"cannot serve on {HOST}:{port}: {e}") from e
        live = cls(server, RunChannels(context, run_dir))
        live._thread.start()
        events.subscribe(EVENT_KINDS, live._on_record)
        return live

    @property
    def url(self) -> str:
        return f"ws://{HOST}:{self.port}"

    @property
    def skipped(self) -> int:
        """Records the mapping could not take (``RunChannels.skipped``)."""
        return self.channels.skipped

    @property
    def dropped(self) -> int:
        """Records pushed out of the queue before the thread got to them."""
        return self._queue.dropped

    def stop(self) -> None:
        """Send what is queued, then close the channels and the server (idempotent)."""
        if self._thread.is_alive():
            self._stopping = True
            self._wake.set()
            self._thread.join()
        self.channels.close()
        self.server.stop()

    def _on_record(self, record: dict[str, Any]) -> None:
        self._queue.put(record)
        self._wake.set()

    def _forward(self) -> None:
        while True:
            self._wake.wait()
            self._wake.clear()  # a put after this sets it again: nothing is left waiting
            while (record := self._queue.take()) is not None:
                self.channels.log(record)
            if self._stopping:
                return
