"""The buoy detector (thesis §5.1.4) on rendered buoys, with the Hough radii scaled by the height."""

from __future__ import annotations

import numpy as np
import pytest

from app.sensors.detect_buoy import BuoyDetector
from sim.camera_render import Conditions
from tests.app.sensors.camera_scenes import BUOY, CAMERA, open_sea, render_at

GLINTS = Conditions(glints=100)


@pytest.mark.parametrize(("pixel", "height_m"), [((640, 480), 1.5), ((400, 300), 4.0), ((900, 650), 8.0)])
def test_buoy_centre_and_diameter_match_the_renderer_truth(pixel, height_m) -> None:
    d = BuoyDetector(BUOY, CAMERA)
    diameter_px = d.expected_radius_px(height_m) * 2
    frame = render_at(pixel, diameter_px, detector=BUOY, attitude_rad=(0.03, -0.04, 0.2))
    found = d.detect(frame.image, 0.0, height_m=height_m)
    assert found is not None and found.marker_id == -1 and found.corners_px == ()
    assert np.hypot(*np.subtract(found.center_px, frame.truth.center_px or (0, 0))) < 1.5
    assert found.size_px == pytest.approx(frame.truth.size_px, rel=0.1)


def test_buoy_is_tracked_in_a_window_on_the_next_frame() -> None:
    d = BuoyDetector(BUOY, CAMERA)
    r_px = d.expected_radius_px(3.0)
    assert d.detect(render_at((500, 500), 2 * r_px, detector=BUOY).image, 0.0, height_m=3.0) is not None
    found = d.detect(render_at((520, 490), 2 * r_px, detector=BUOY, frame_index=1).image, 0.033, height_m=3.0)
    assert found is not None and found.tracked


def test_open_sea_and_its_glints_are_not_a_buoy() -> None:
    assert BuoyDetector(BUOY, CAMERA).detect(open_sea(), 0.0, height_m=6.0) is None


@pytest.mark.parametrize("diameter_px", [200.0, 400.0])
@pytest.mark.parametrize(("out_x", "out_y"), [(0.2, None), (0.4, None), (None, 0.3), (0.1, 0.1)])
def test_a_buoy_cut_by_the_image_edge_is_found_on_its_rim_where_it_is(diameter_px, out_x, out_y) -> None:
    """Low over the buoy (here 0.75 and 0.375 m) it spills over the image's edge: its centre and size come from a
    circle on the rim left in the image — the cut disc's centroid lay 0.064 D (a fifth out) to 0.16 D (two fifths
    out) inside the true centre, and its area gave a diameter 8–21 % short."""
    d = BuoyDetector(BUOY, CAMERA)
    height_m = CAMERA.fx_px * BUOY.buoy_diameter_m / diameter_px
    x = CAMERA.width_px - diameter_px / 2 + out_x * diameter_px if out_x is not None else 640.0
    y = CAMERA.height_px - diameter_px / 2 + out_y * diameter_px if out_y is not None else 480.0
    frame = render_at((x, y), diameter_px, detector=BUOY, attitude_rad=(0.1, -0.15, 1.0), conditions=GLINTS)
    assert not frame.truth.in_view  # the renderer's own verdict: not wholly in the image
    found = d.detect(frame.image, 0.0, height_m=height_m)
    assert found is not None
    print(diameter_px, out_x, out_y, found.center_px, (x, y), found.size_px)
    assert np.hypot(found.center_px[0] - x, found.center_px[1] - y) < 1.5
    assert found.size_px == pytest.approx(diameter_px, rel=0.02)
