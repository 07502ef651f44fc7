"""The auto-exposure controller on its own: proportional steps, the band, settling, on/off."""

from __future__ import annotations

import numpy as np
import pytest

from app.sensors.camera import ExposureControls
from app.sensors.exposure import AutoExposure, AutoExposureConfig, mean_brightness


def test_inside_the_band_nothing_changes() -> None:
    ae = AutoExposure()
    for mean in (100.0, 120.0, 140.0):
        assert ae.update(mean, ExposureControls(32.0, 48.0)) is None


def test_step_is_proportional_to_the_error_and_aims_at_the_band_centre() -> None:
    config = AutoExposureConfig(gain=1.0)
    slightly = AutoExposure(config).update(150.0, ExposureControls(32.0, 48.0))
    far = AutoExposure(config).update(240.0, ExposureControls(32.0, 48.0))
    assert slightly is not None and far is not None
    assert slightly.exposure == pytest.approx(48.0 * 120.0 / 150.0)  # one step to the centre on a linear sensor
    assert far.exposure == pytest.approx(48.0 * 120.0 / 240.0)
    assert slightly.brightness == 32.0


def test_a_black_or_saturated_frame_gets_the_largest_step() -> None:
    config = AutoExposureConfig(max_step_ratio=4.0)
    up = AutoExposure(config).update(0.0, ExposureControls(32.0, 10.0))
    down = AutoExposure(config).update(255.0, ExposureControls(32.0, 400.0))
    assert up is not None and up.exposure == pytest.approx(40.0)
    assert down is not None and down.exposure == pytest.approx(100.0)


def test_waits_for_a_frame_taken_with_the_last_request() -> None:
    ae = AutoExposure()
    request = ae.update(60.0, ExposureControls(32.0, 48.0))
    assert request is not None
    assert ae.update(60.0, ExposureControls(32.0, 48.0)) is None  # still the old exposure: no second step
    assert ae.update(60.0, request) is not None  # the request has arrived and is still too dark


def test_exposure_stays_within_its_limits() -> None:
    ae = AutoExposure(AutoExposureConfig(max_exposure=50.0))
    assert ae.update(10.0, ExposureControls(32.0, 50.0)) is None


def test_switched_off_it_requests_nothing_and_switched_on_it_starts_afresh() -> None:
    ae = AutoExposure(enabled=False)
    assert ae.update(10.0, ExposureControls()) is None
    ae.set_enabled(True)
    assert ae.update(10.0, ExposureControls()) is not None


def test_mean_brightness_of_a_frame() -> None:
    image = np.full((960, 1280), 90, np.uint8)
    image[:, 640:] = 150
    assert mean_brightness(image) == pytest.approx(120.0)
