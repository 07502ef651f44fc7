"""The evaluation's geometric camera and the real buoy detector agree on when a buoy cut by the image's edge is
still found: the model (``sim.pickup_world.rim_in_image`` ≥ ``BUOY_RIM_IN_IMAGE``) against ``BuoyDetector`` on
rendered frames, low over the buoy with a tilted vehicle and glints on the sea."""

from __future__ import annotations

import numpy as np
import pytest

from app.sensors.detect_buoy import BuoyDetector
from sim.camera_render import Conditions
from sim.pickup_world import BUOY_RIM_IN_IMAGE, rim_in_image
from tests.app.sensors.camera_scenes import BUOY, CAMERA, render_at

W, H = CAMERA.width_px, CAMERA.height_px


def test_the_rim_share_of_circles_in_and_out_of_the_image() -> None:
    assert rim_in_image((640.0, 480.0), 100.0, W, H) == 1.0
    assert rim_in_image((W - 1.0, 480.0), 100.0, W, H) == pytest.approx(0.5, abs=0.02)  # centre on the edge
    assert rim_in_image((-1.0, -1.0), 100.0, W, H) == pytest.approx(0.25, abs=0.02)  # centre on a corner
    assert rim_in_image((-200.0, 480.0), 100.0, W, H) == 0.0


# (diameter px, share of the diameter beyond the right edge, … beyond the bottom edge)
CASES = [
    (200.0, 0.0, 0.0), (200.0, 0.2, 0.0), (200.0, 0.3, 0.0), (200.0, 0.0, 0.3), (200.0, 0.1, 0.1),
    (200.0, 0.48, 0.0), (200.0, 0.6, 0.0), (200.0, 0.25, 0.25), (200.0, 0.2, 0.2),
    (500.0, 0.2, 0.0), (500.0, 0.3, 0.0), (500.0, 0.1, 0.1), (500.0, 0.48, 0.0), (500.0, 0.25, 0.25),
]  # fmt: skip


@pytest.mark.parametrize(("diameter_px", "out_x", "out_y"), CASES)
def test_the_model_says_found_only_where_the_detector_finds_the_buoy_where_it_is(diameter_px, out_x, out_y) -> None:
    """Where the model says found, the detector finds the buoy within 1.5 px; where less than half its outline is
    in the image, neither does. (Between 53 % and 60 % the detector still finds it and the model does not: the
    evaluation errs blind.)"""
    height_m = CAMERA.fx_px * BUOY.buoy_diameter_m / diameter_px
    x = (W - diameter_px / 2 + out_x * diameter_px) if out_x else 640.0
    y = (H - diameter_px / 2 + out_y * diameter_px) if out_y else 480.0
    share = rim_in_image((x, y), diameter_px / 2, W, H)
    frame = render_at(
        (x, y), diameter_px, detector=BUOY, attitude_rad=(0.1, -0.15, 1.0), conditions=Conditions(glints=100)
    )
    found = BuoyDetector(BUOY, CAMERA).detect(frame.image, 0.0, height_m=height_m)
    print(diameter_px, out_x, out_y, f"rim {share:.2f}", found and found.center_px, (x, y))
    if share >= BUOY_RIM_IN_IMAGE:
        assert found is not None and np.hypot(found.center_px[0] - x, found.center_px[1] - y) < 1.5
    if share < 0.5:
        assert found is None
