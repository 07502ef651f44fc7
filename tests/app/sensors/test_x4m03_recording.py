"""Recordings: seapick's own format round-trips; Novelda datafloat and baseband_iq files are read by their layout."""

from __future__ import annotations

import struct

import numpy as np
import pytest

from app.messages import RadarFrame, RangeAxis
from app.sensors.x4m03_frame_area import quantise_frame_area
from app.sensors.x4m03_recording import THESIS_AXIS, RecordingError, RecordingWriter, read_recording

AXIS = quantise_frame_area(0.4, 5.0, 0.18)


def frames(n: int, axis: RangeAxis = AXIS) -> list[RadarFrame]:
    rng = np.random.default_rng(0)
    z = (rng.normal(0, 1e-3, (n, axis.bins)) + 1j * rng.normal(0, 1e-3, (n, axis.bins))).astype(np.complex64)
    return [RadarFrame(10.0 + 0.1 * k, 100 + k, axis, z[k]) for k in range(n)]


def test_seapick_recording_round_trips_frames_bit_for_bit(tmp_path):
    path = tmp_path / "a.x4rec"
    original = frames(5)
    with RecordingWriter(path, AXIS, {"fps_hz": 10.032}) as w:
        for f in original:
            w.write(f)
    rec = read_recording(path)
    assert (rec.kind, rec.axis, len(rec), rec.header["fps_hz"]) == ("seapick", AXIS, 5, 10.032)
    for a, b in zip(original, rec.frames(), strict=True):
        assert (a.t_s, a.frame_counter) == (b.t_s, b.frame_counter)
        assert np.array_equal(a.baseband, b.baseband)


def test_a_recording_cut_off_mid_record_keeps_the_whole_frames_and_counts_the_rest(tmp_path):
    path = tmp_path / "cut.x4rec"
    with RecordingWriter(path, AXIS) as w:
        for f in frames(3):
            w.write(f)
    path.write_bytes(path.read_bytes()[:-100])
    rec = read_recording(path)
    assert len(rec) == 2 and rec.truncated_bytes > 0


def test_a_frame_on_another_axis_is_refused_by_the_writer(tmp_path):
    other = frames(1, RangeAxis(0.3343, AXIS.bin_m, 53))[0]
    with RecordingWriter(tmp_path / "b.x4rec", AXIS) as w, pytest.raises(ValueError, match="differs"):
        w.write(other)


def datafloat_bytes(counters: list[int], n: int) -> bytes:
    out = b""
    for c in counters:
        values = np.concatenate([np.full(n // 2, 0.001 * c), np.full(n // 2, -0.002)]).astype("<f4")
        out += struct.pack("<III", 0, c, n) + values.tobytes()
    return out


def test_novelda_datafloat_file_reads_with_the_thesis_axis_and_counter_times(tmp_path):
    path = tmp_path / "xethru_datafloat_20190415_120000.dat"
    path.write_bytes(datafloat_bytes([7, 8, 10], 182))  # 740-byte records
    rec = read_recording(path, fps_hz=10.0)
    assert rec.kind == "xethru_datafloat" and rec.axis == THESIS_AXIS
    assert rec.t_s.tolist() == [0.0, 0.1, 0.3]
    assert rec.baseband[2, 0] == pytest.approx(0.010 - 0.002j)


def test_a_datafloat_file_that_does_not_fit_the_thesis_axis_asks_for_one(tmp_path):
    path = tmp_path / "xethru_datafloat_x.dat"
    path.write_bytes(datafloat_bytes([1, 2], 106))
    with pytest.raises(RecordingError, match="give the range axis"):
        read_recording(path)
    rec = read_recording(path, axis=RangeAxis(0.334321, 0.0514403, 53))
    assert rec.baseband.shape == (2, 53)


def test_novelda_baseband_iq_file_carries_its_own_axis(tmp_path):
    path = tmp_path / "xethru_baseband_iq_20170913_150437.dat"
    bins, data = 53, b""
    for c in (1, 2):
        data += struct.pack("<IIffff", c, bins, 0.0514403, 2.916e9, 7.29e9, 0.334320992)
        data += np.full(bins, 0.01, "<f4").tobytes() + np.full(bins, 0.02, "<f4").tobytes()
    path.write_bytes(data)
    rec = read_recording(path, fps_hz=17.0)
    assert rec.axis.bins == 53 and rec.axis.start_m == pytest.approx(0.334321, abs=1e-6)
    assert rec.baseband[1, 5] == pytest.approx(0.01 + 0.02j) and rec.t_s[1] == pytest.approx(1 / 17)


def test_unknown_or_inconsistent_files_are_clear_errors(tmp_path):
    junk = tmp_path / "notes.txt"
    junk.write_bytes(b"hello radar")
    with pytest.raises(RecordingError, match="not a seapick recording"):
        read_recording(junk)
    bad = tmp_path / "xethru_datafloat_bad.dat"
    bad.write_bytes(datafloat_bytes([1], 182) + struct.pack("<III", 0, 2, 180) + bytes(4 * 182))
    with pytest.raises(RecordingError, match="byte 740: record says 180 floats"):
        read_recording(bad)
