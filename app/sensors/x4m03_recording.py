"""Radar recordings: seapick's own format (write and read), and Novelda's DataRecorder files (read).

seapick ``.x4rec`` — a magic line, one JSON header line, then one record per frame, all little-endian::

    SEAPICK-X4REC 1\\n
    {"axis": {"start_m": …, "bin_m": …, "bins": …}, "fps_hz": …, …}\\n
    f64 t_s | u32 frame_counter | u32 n | f32[n]        (n = 2·bins: the DataFloat values as sent, I then Q)

Novelda (reference §9), read only; the files carry no timestamps (``t_s = (counter − first) / fps``):

- ``xethru_datafloat_*.dat``: ``u32 content_id | u32 frame_counter | u32 n | f32[n]`` — no range axis in
  the file: pass one, or the thesis settings' axis (0.4–5.0 m, offset 0.18) is assumed when n = 182;
- ``xethru_baseband_iq_*.dat``: ``u32 frame_counter | u32 bins | f32 bin_length | f32 fs | f32 fc |
  f32 range_offset | f32 I[bins] | f32 Q[bins]`` — the axis comes with every record.

A file that is not one of these, or a record that contradicts its header, is a ``RecordingError`` naming
the byte offset; a truncated last record (recording cut off) is dropped and counted.
"""

from __future__ import annotations

import json
import math
import struct
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import IO, Any

import numpy as np

from app.errors import AppError
from app.messages import RadarFrame, RangeAxis
from app.sensors.x4m03_frame_area import quantise_frame_area

MAGIC = b"SEAPICK-X4REC 1\n"
SEAPICK_RECORD = struct.Struct("<dII")
DATAFLOAT_RECORD = struct.Struct("<III")
BASEBAND_RECORD = struct.Struct("<IIffff")
DEFAULT_FPS_HZ = 10.032052556  # the thesis's fps 10, as the X4 runs it
THESIS_AXIS = quantise_frame_area(0.4, 5.0, 0.18)


class RecordingError(AppError):
    """Raised when a recording cannot be read: unknown format or a bad record (``path``, ``offset``)."""

    def __init__(self, path: Path, offset: int, message: str) -> None:
        self.path = path
        self.offset = offset
        super().__init__(f"{path}: byte {offset}: {message}")


@dataclass(eq=False)
class Recording:
    """Frames of one recording: ``baseband`` (frames × bins, complex64), their times and counters."""

    path: Path
    kind: str  # "seapick", "xethru_datafloat", "xethru_baseband_iq"
    axis: RangeAxis
    t_s: np.ndarray
    counters: np.ndarray
    baseband: np.ndarray
    header: dict[str, Any] = field(default_factory=dict)
    truncated_bytes: int = 0

    def __len__(self) -> int:
        return len(self.t_s)

    def frames(self) -> Iterator[RadarFrame]:
        for t_s, counter, z in zip(self.t_s, self.counters, self.baseband, strict=True):
            yield RadarFrame(float(t_s), int(counter), self.axis, z)


class RecordingWriter:
    """Appends frames to a seapick recording (one axis per file), flushed per frame."""

    def __init__(self, path: Path, axis: RangeAxis, header: dict[str, Any] | None = None) -> None:
        self.path = path
        self.axis = axis
        self.frames = 0
        head = {"axis": {"start_m": axis.start_m, "bin_m": axis.bin_m, "bins": axis.bins}, **(header or {})}
        self._file: IO[bytes] | None = path.open("wb")
        self._file.write(MAGIC + json.dumps(head).encode() + b"\n")

    def write(self, frame: RadarFrame) -> None:
        if self._file is None:
            raise ValueError(f"{self.path} is closed")
        if frame.axis != self.axis:
            raise ValueError(f"frame axis {frame.axis} differs from the recording's {self.axis}")
        values = np.concatenate([frame.baseband.real, frame.baseband.imag]).astype("<f4")
        self._file.write(SEAPICK_RECORD.pack(frame.t_s, frame.frame_counter, values.size) + values.tobytes())
        self._file.flush()
        self.frames += 1

    def close(self) -> None:
        if self._file is not None:
            self._file.close()
            self._file = None

    def __enter__(self) -> RecordingWriter:
        return self

    def __exit__(self, *_: object) -> None:
        self.close()


def read_recording(path: Path, axis: RangeAxis | None = None, fps_hz: float = DEFAULT_FPS_HZ) -> Recording:
    """Read any supported recording (detected from its content and name); ``axis``/``fps_hz`` for Novelda files."""
    data = Path(path).read_bytes()
    if data.startswith(MAGIC):
        return _read_seapick(Path(path), data)
    name = Path(path).name
    if name.startswith("xethru_baseband_iq") or name.startswith("xethru_baseband_ap"):
        if name.startswith("xethru_baseband_ap"):
            raise RecordingError(Path(path), 0, "baseband amplitude/phase recordings are not supported (use IQ)")
        return _read_baseband_iq(Path(path), data, fps_hz)
    if name.startswith("xethru_datafloat") or _looks_like_datafloat(data):
        return _read_datafloat(Path(path), data, axis, fps_hz)
    raise RecordingError(Path(path), 0, "not a seapick recording, nor a Novelda datafloat or baseband_iq file")


def _read_seapick(path: Path, data: bytes) -> Recording:
    end = data.find(b"\n", len(MAGIC))
    try:
        header = json.loads(data[len(MAGIC) : end])
        a = header["axis"]
        axis = RangeAxis(float(a["start_m"]), float(a["bin_m"]), int(a["bins"]))
    except (ValueError, KeyError, TypeError) as e:
        raise RecordingError(path, len(MAGIC), f"bad header: {e}") from e
    n = 2 * axis.bins
    size = SEAPICK_RECORD.size + 4 * n
    body = data[end + 1 :]
    count, truncated = divmod(len(body), size)
    records = np.frombuffer(
        body, dtype=np.dtype([("t", "<f8"), ("c", "<u4"), ("n", "<u4"), ("v", "<f4", (n,))]), count=count
    )
    bad = np.flatnonzero(records["n"] != n)
    if bad.size:
        offset = end + 1 + int(bad[0]) * size
        raise RecordingError(path, offset, f"record says {records['n'][bad[0]]} floats, the header {n}")
    return Recording(
        path,
        "seapick",
        axis,
        records["t"].copy(),
        records["c"].astype(np.int64),
        _iq(records["v"], axis.bins),
        header,
        truncated,
    )


def _looks_like_datafloat(data: bytes) -> bool:
    if len(data) < DATAFLOAT_RECORD.size:
        return False
    content_id, _, n = DATAFLOAT_RECORD.unpack_from(data)
    return content_id == 0 and 0 < n <= 4096 and len(data) >= DATAFLOAT_RECORD.size + 4 * n


def _read_datafloat(path: Path, data: bytes, axis: RangeAxis | None, fps_hz: float) -> Recording:
    if len(data) < DATAFLOAT_RECORD.size:
        raise RecordingError(path, 0, "empty datafloat file")
    n = DATAFLOAT_RECORD.unpack_from(data)[2]
    if axis is None:
        if n != 2 * THESIS_AXIS.bins:
            raise RecordingError(path, 0, f"{n} floats per frame: give the range axis (the file has none)")
        axis = THESIS_AXIS
    if n != 2 * axis.bins:
        raise RecordingError(path, 0, f"{n} floats per frame do not fit a {axis.bins}-bin baseband axis")
    size = DATAFLOAT_RECORD.size + 4 * n
    count, truncated = divmod(len(data), size)
    records = np.frombuffer(
        data, dtype=np.dtype([("id", "<u4"), ("c", "<u4"), ("n", "<u4"), ("v", "<f4", (n,))]), count=count
    )
    bad = np.flatnonzero(records["n"] != n)
    if bad.size:
        raise RecordingError(path, int(bad[0]) * size, f"record says {records['n'][bad[0]]} floats, not {n}")
    counters = records["c"].astype(np.int64)
    return Recording(
        path,
        "xethru_datafloat",
        axis,
        (counters - counters[:1]) / fps_hz,
        counters,
        _iq(records["v"], axis.bins),
        {"fps_hz": fps_hz},
        truncated,
    )


def _read_baseband_iq(path: Path, data: bytes, fps_hz: float) -> Recording:
    if len(data) < BASEBAND_RECORD.size:
        raise RecordingError(path, 0, "empty baseband_iq file")
    _, bins, bin_m, _, _, offset_m = BASEBAND_RECORD.unpack_from(data)
    if not 0 < bins <= 4096:
        raise RecordingError(path, 0, f"implausible bin count {bins}")
    if not (math.isfinite(bin_m) and 0.0 < bin_m <= 1.0) or not math.isfinite(offset_m):
        raise RecordingError(path, 0, f"implausible range axis: bin length {bin_m:g} m, offset {offset_m:g} m")
    size = BASEBAND_RECORD.size + 8 * bins
    count, truncated = divmod(len(data), size)
    layout = [
        ("c", "<u4"),
        ("bins", "<u4"),
        ("bin", "<f4"),
        ("fs", "<f4"),
        ("fc", "<f4"),
        ("off", "<f4"),
        ("i", "<f4", (bins,)),
        ("q", "<f4", (bins,)),
    ]
    records = np.frombuffer(data, dtype=np.dtype(layout), count=count)
    bad = np.flatnonzero((records["bins"] != bins) | (records["off"] != offset_m))
    if bad.size:
        raise RecordingError(path, int(bad[0]) * size, "the bin count or range offset changes between records")
    counters = records["c"].astype(np.int64)
    axis = RangeAxis(float(offset_m), float(bin_m), int(bins))
    baseband = (records["i"] + 1j * records["q"]).astype(np.complex64)
    header = {"fps_hz": fps_hz, "fs_hz": float(records["fs"][0]), "fc_hz": float(records["fc"][0])} if count else {}
    return Recording(
        path, "xethru_baseband_iq", axis, (counters - counters[:1]) / fps_hz, counters, baseband, header, truncated
    )


def _iq(values: np.ndarray, bins: int) -> np.ndarray:
    return (values[:, :bins] + 1j * values[:, bins:]).astype(np.complex64)
