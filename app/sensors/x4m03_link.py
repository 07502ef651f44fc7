"""The thread bridge of the X4M03 driver: a pyserial port, a blocking reader thread, and the hand-over to asyncio.

The reader thread blocks in ``serial.read`` (no timeout, no polling: ``cancel_read`` wakes it to stop),
feeds the bytes to the streaming parser and passes each batch of decoded messages to the event loop with
``call_soon_threadsafe``. When the port fails (unplugged: the read raises), it reports the loss the same
way and ends. pyserial errors are translated into ``RadarDisconnected`` here, at the boundary.
"""

from __future__ import annotations

import asyncio
import threading
from collections.abc import Callable
from typing import TypeVar

import serial

from app.sensors.radar import RadarDisconnected
from app.sensors.x4m03_codec import Message
from app.sensors.x4m03_parser import X4M03Parser

T = TypeVar("T")


class SerialLink:
    """One open port: ``open`` and ``write`` block (call them through ``asyncio.to_thread``)."""

    def __init__(
        self,
        port: str,
        baudrate: int,
        parser: X4M03Parser,
        loop: asyncio.AbstractEventLoop,
        on_messages: Callable[[list[Message]], None],
        on_lost: Callable[[RadarDisconnected], None],
    ) -> None:
        self.port = port
        self._baudrate = baudrate
        self._parser = parser
        self._loop = loop
        self._on_messages = on_messages
        self._on_lost = on_lost
        self._serial: serial.Serial | None = None
        self._thread: threading.Thread | None = None
        self._closing = threading.Event()
        self._write_lock = threading.Lock()

    def open(self) -> None:
        """Open the port, drop whatever it held (boot messages, half frames), start the reader thread."""
        try:
            ser = serial.Serial(self.port, self._baudrate, timeout=None, write_timeout=None)
            ser.reset_input_buffer()
        except (serial.SerialException, OSError, ValueError) as e:
            raise RadarDisconnected(self.port, f"cannot open: {e}") from e
        self._serial = ser
        self._parser.reset()
        self._thread = threading.Thread(target=self._read_loop, name=f"x4m03.reader {self.port}", daemon=True)
        self._thread.start()

    def write(self, data: bytes) -> None:
        ser = self._serial
        if ser is None:
            raise RadarDisconnected(self.port, "port is not open")
        try:
            with self._write_lock:
                ser.write(data)
        except (serial.SerialException, OSError) as e:
            raise RadarDisconnected(self.port, f"write failed: {e}") from e

    def close(self) -> None:
        """Stop the reader thread and close the port (idempotent)."""
        self._closing.set()
        ser, self._serial = self._serial, None
        if ser is not None:
            try:
                ser.cancel_read()
            except (serial.SerialException, OSError):
                pass
        if self._thread is not None and self._thread is not threading.current_thread():
            self._thread.join()
        self._thread = None
        if ser is not None:
            try:
                ser.close()
            except (serial.SerialException, OSError):
                pass

    def _read_loop(self) -> None:
        ser = self._serial
        assert ser is not None
        while not self._closing.is_set():
            try:
                data = ser.read(max(1, ser.in_waiting))
            except (serial.SerialException, OSError, TypeError) as e:  # TypeError: closed under our feet
                if not self._closing.is_set():
                    self._hand_over(self._on_lost, RadarDisconnected(self.port, f"read failed: {e}"))
                return
            if not data:
                continue  # cancel_read: the loop condition decides
            messages = self._parser.feed(data)
            if messages:
                self._hand_over(self._on_messages, messages)

    def _hand_over(self, callback: Callable[[T], None], arg: T) -> None:
        try:
            self._loop.call_soon_threadsafe(callback, arg)
        except RuntimeError:  # the loop is closed: nobody is listening any more
            self._closing.set()
