"""``python -m app.replay radar`` on vendor-like X4 baseband files: short, cut off, with NaN/inf, bad options."""

from __future__ import annotations

import json
import struct
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from app.estimators.radar_altitude import RadarAltitudeEstimator
from app.messages import RadarFrame, RangeAxis
from app.settings import RadarAltitudeSettings

ROOT = Path(__file__).resolve().parents[2]
AXIS = RangeAxis(0.334320992, 0.0514403, 91)
FPS_HZ = 17.0


def sea_frames(n=400, seed=5, height_m=2.0):
    """Baseband of a sea echo bobbing ±3 cm around ``height_m`` (phase turning), a static direct path, noise."""
    rng = np.random.default_rng(seed)
    r = AXIS.start_m + AXIS.bin_m * np.arange(AXIS.bins)
    out = []
    for i in range(n):
        h = height_m + 0.03 * np.sin(2 * np.pi * 0.4 * i / FPS_HZ)
        sea = 0.02 * np.exp(-0.5 * ((r - h) / 0.07) ** 2) * np.exp(-1j * 4 * np.pi * h / 0.0411)
        direct = 0.05 * np.exp(-0.5 * ((r - 0.4) / 0.05) ** 2)
        noise = 2e-4 * (rng.standard_normal(AXIS.bins) + 1j * rng.standard_normal(AXIS.bins))
        out.append((sea + direct + noise).astype(np.complex64))
    return np.array(out)


def baseband_iq_bytes(frames, bin_m=AXIS.bin_m):
    data = b""
    for c, z in enumerate(frames, start=1):
        data += struct.pack("<IIffff", c, AXIS.bins, bin_m, 2.916e9, 7.29e9, AXIS.start_m)
        data += z.real.astype("<f4").tobytes() + z.imag.astype("<f4").tobytes()
    return data


def write(tmp_path, frames, name="xethru_baseband_iq_20170913_150437.dat", **kw):
    path = tmp_path / name
    path.write_bytes(baseband_iq_bytes(frames, **kw))
    return path


def replay(*args):
    return subprocess.run(
        [sys.executable, "-m", "app.replay", "radar", *map(str, args)], cwd=ROOT, capture_output=True, text=True,
        timeout=120,
    )  # fmt: skip


def summary_of(path, *extra):
    proc = replay(path, "--json", "--plot", "", "--fps", FPS_HZ, *extra)
    assert proc.returncode == 0, proc.stderr
    return json.loads(proc.stdout)


def test_one_nan_or_inf_frame_costs_one_frame_not_the_rest_of_the_recording(tmp_path):
    frames = sea_frames()
    clean = summary_of(write(tmp_path, frames, name="xethru_baseband_iq_clean.dat"))["summary"]
    bad = frames.copy()
    bad[150, :] = np.nan  # a corrupt record
    bad[250, 32] = np.inf  # one bin, at the sea's range
    doc = summary_of(write(tmp_path, bad))
    s = doc["summary"]
    print(f"tracked frames: clean {clean['tracking']}, with a NaN and an inf frame {s['tracking']}")
    assert clean["tracking"] >= 350
    assert s["tracking"] >= clean["tracking"] - 2 and s["non_finite_frames"] == 2
    assert s["frames"] == 400 and s["tracking"] + s["holding"] + s["lost"] == 400
    assert doc["frames"][150]["status"] == "holding" and doc["frames"][150]["range_m"] is None
    assert abs(doc["frames"][300]["altitude_m"] - 2.0) < 0.06


def test_the_estimator_rejects_counts_and_recovers_from_non_finite_frames():
    est = RadarAltitudeEstimator(RadarAltitudeSettings(method="clutter_map"))
    frames = sea_frames(120)
    out = []
    for i, z in enumerate(frames):
        if i == 60:
            z = z.copy()
            z[:] = np.nan
        out.append(est.update(RadarFrame(i / FPS_HZ, i, AXIS, z)))
    assert est.rejected_non_finite == 1
    assert out[60].status == "holding" and not out[60].accepted
    assert all(e.status == "tracking" for e in out[61:])


def test_an_echo_in_the_first_or_last_bin_is_not_a_peak():
    for height_m in (AXIS.start_m - 0.08, AXIS.end_m + 0.08):  # the echo's flank: strongest in the edge bin
        est = RadarAltitudeEstimator(RadarAltitudeSettings(method="clutter_map"))
        got = [est.update(RadarFrame(i / FPS_HZ, i, AXIS, z)) for i, z in enumerate(sea_frames(60, height_m=height_m))]
        assert not any(e.accepted for e in got), [e.altitude_m for e in got if e.accepted][:3]


def test_a_file_shorter_than_one_frame_is_one_line_and_exit_2(tmp_path):
    path = write(tmp_path, sea_frames(1))
    path.write_bytes(path.read_bytes()[:500])  # cut off inside the first frame
    proc = replay(path, "--plot", str(tmp_path / "p.png"))
    assert proc.returncode == 2 and "Traceback" not in proc.stderr
    assert proc.stderr.strip() == f"cannot replay: {path} holds no complete frame (500 bytes)"


def test_an_unwritable_plot_still_gives_the_json_and_one_line(tmp_path):
    path = write(tmp_path, sea_frames(40))
    proc = replay(path, "--json", "--fps", FPS_HZ, "--plot", "/proc/seapick/plot.png")
    assert proc.returncode == 1, proc.stderr
    doc = json.loads(proc.stdout)
    assert doc["summary"]["frames"] == 40 and doc["figure"] is None
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("cannot write the plot /proc/seapick/plot.png")


@pytest.mark.parametrize(
    ("args", "expected"),
    [
        (["--axis", "0.4", "-0.05", "91"], "--axis BIN_M -0.05 is outside 0 (exclusive)..1 m"),
        (["--axis", "0.4", "0.05", "9.5"], "--axis BINS 9.5 is not a whole number"),
        (["--fps", "0"], "argument --fps: 0 is outside 0.01..1000 Hz"),
        (["--threshold", "nan"], "argument --threshold: nan is outside"),
        (["--calibration-frames", "-3"], "argument --calibration-frames: -3 is outside"),
    ],
)
def test_bad_options_are_one_line_and_exit_2(tmp_path, args, expected):
    path = write(tmp_path, sea_frames(3))
    proc = replay(path, *args)
    lines = proc.stderr.strip().splitlines()
    assert proc.returncode == 2 and len(lines) == 1 and expected in lines[0], proc.stderr


def test_a_vendor_file_with_a_negative_bin_length_is_refused(tmp_path):
    path = write(tmp_path, sea_frames(3), bin_m=-0.0514403)
    proc = replay(path)
    assert proc.returncode == 2 and "implausible range axis: bin length -0.0514403 m" in proc.stderr


def test_help_explains_the_command_and_every_option():
    top = subprocess.run([sys.executable, "-m", "app.replay", "--help"], cwd=ROOT, capture_output=True, text=True)
    assert top.returncode == 0 and "altitude estimator" in top.stdout and "Exit status" in top.stdout
    sub = replay("--help")
    assert sub.returncode == 0
    for option in ("--json", "--calibration-frames", "--threshold", "--axis", "--fps", "--plot"):
        line = next(x for x in sub.stdout.splitlines() if x.strip().startswith(option))
        assert len(line.split(option, 1)[1].strip()) > 3 or option == "--axis", line  # each has a help text
    assert "Novelda" in sub.stdout
