"""The detector interface: picking a detector by kind, tracking windows, the detector's own prediction."""

from __future__ import annotations

import pytest

from app.messages import PixelDetection
from app.sensors.detect import Track, Window, make_detector
from app.sensors.detect_buoy import BuoyDetector
from app.sensors.detect_marker import MarkerDetector
from app.settings import CameraSettings, DetectorSettings


def fix(t_s: float, x: float, y: float) -> PixelDetection:
    return PixelDetection(t_s, (x, y), (), 50.0, 0.3, 7, False)


def test_settings_kind_picks_the_detector() -> None:
    camera = CameraSettings()
    assert isinstance(make_detector(DetectorSettings(kind="aruco"), camera), MarkerDetector)
    assert isinstance(make_detector(DetectorSettings(kind="buoy"), camera), BuoyDetector)


def test_window_is_clipped_to_the_image() -> None:
    w = Window.around((10.0, 950.0), 100.0, 1280, 960)
    assert (w.x0, w.y0, w.x1, w.y1) == (0, 900, 61, 960)
    assert Window.around((-500.0, 0.0), 100.0, 1280, 960).empty


def test_track_predicts_with_the_last_frame_to_frame_motion() -> None:
    track = Track()
    assert track.hint(0.0) is None
    track.update(fix(0.0, 100.0, 200.0))
    track.update(fix(0.1, 110.0, 195.0))
    hint = track.hint(0.2)
    assert hint is not None
    assert hint.center_px == pytest.approx((120.0, 190.0))
    assert hint.size_px == 50.0 and hint.radius_px > 0.0


def test_track_is_dropped_after_a_miss() -> None:
    track = Track()
    track.update(fix(0.0, 100.0, 200.0))
    track.update(None)
    assert track.hint(0.1) is None
