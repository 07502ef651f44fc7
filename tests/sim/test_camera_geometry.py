"""Geometric camera mode: corners where the pinhole says, in ArUco order, with the stated noise and truth."""

from __future__ import annotations

import math

import numpy as np
import pytest

from app.settings import CameraSettings
from sim.camera_geometry import GeometricCamera, marker_corners_ned

CAM = CameraSettings(lever_arm_frd_m=(0.0, 0.0, 0.0))


def above(height_m, north_m=0.0, east_m=0.0):
    return (north_m, east_m, -height_m)


def test_a_marker_straight_below_a_level_camera_is_centred_upright_and_f_s_over_h_wide():
    g = GeometricCamera(CAM, marker_size_m=0.4, pixel_noise_std_px=0.0)
    f = g.frame(0.0, above(10.0), 0.0, 0.0, 0.0, (0.0, 0.0, 0.0))
    assert f.visible
    np.testing.assert_allclose(f.centre_true_px, (CAM.cx_px, CAM.cy_px), atol=1e-9)
    tl, tr, br, bl = f.corners_true_px
    assert tl[0] < tr[0] and tl[1] < bl[1] and br[0] > bl[0] and br[1] > tr[1]  # TL, TR, BR, BL on screen
    assert tr[0] - tl[0] == pytest.approx(CAM.fx_px * 0.4 / 10.0)
    assert f.camera_height_m == pytest.approx(10.0) and f.radar_height_m == pytest.approx(10.0)


def test_heading_east_turns_north_to_the_left_of_the_image():
    g = GeometricCamera(CAM, pixel_noise_std_px=0.0)
    f = g.frame(0.0, above(10.0), 0.0, 0.0, math.radians(90.0), (1.0, 0.0, 0.0))
    u, v = f.centre_true_px
    assert u < CAM.cx_px - 50 and v == pytest.approx(CAM.cy_px)


def test_pixel_noise_has_the_stated_spread_and_the_seed_repeats_it():
    g = GeometricCamera(CAM, pixel_noise_std_px=0.7, seed=5)
    d = np.vstack([(f.corners_px - f.corners_true_px) for f in
                   (g.frame(0.0, above(8.0), 0.1, -0.1, 0.3, (0.5, 0.2, 0.0)) for _ in range(500))])  # fmt: skip
    assert abs(d.mean()) < 0.05 and d.std() == pytest.approx(0.7, rel=0.05)
    a = GeometricCamera(CAM, seed=9).frame(0.0, above(8.0), 0.0, 0.0, 0.0, (0.0, 0.0, 0.0)).corners_px
    b = GeometricCamera(CAM, seed=9).frame(0.0, above(8.0), 0.0, 0.0, 0.0, (0.0, 0.0, 0.0)).corners_px
    np.testing.assert_array_equal(a, b)


@pytest.mark.parametrize(
    ("vehicle", "marker"),
    [(above(5.0), (30.0, 0.0, 0.0)), (above(5.0), (0.0, 0.0, -10.0)), (above(5.0), (3.0, 3.9, 0.0))],
    ids=["far-outside", "above-the-camera", "partly-outside"],
)
def test_markers_out_of_view_are_not_visible(vehicle, marker):
    assert not GeometricCamera(CAM).frame(0.0, vehicle, 0.0, 0.0, 0.0, marker).visible


def test_lever_arms_and_tilt_give_the_true_camera_and_radar_heights():
    cam = CameraSettings(lever_arm_frd_m=(0.2, 0.0, 0.1))
    g = GeometricCamera(cam, radar_arm_frd_m=(-0.3, 0.0, 0.05), pixel_noise_std_px=0.0)
    pitch = math.radians(10.0)  # nose up: the forward camera rises, the aft radar sinks
    f = g.frame(0.0, above(6.0), 0.0, pitch, 0.0, (1.0, 0.0, 0.0))
    cam_down = -6.0 - 0.2 * math.sin(pitch) + 0.1 * math.cos(pitch)
    radar_down = -6.0 + 0.3 * math.sin(pitch) + 0.05 * math.cos(pitch)
    assert f.camera_pos_ned_m[2] == pytest.approx(cam_down)
    assert f.camera_height_m == pytest.approx(-cam_down)
    assert f.radar_height_m == pytest.approx(-radar_down)
    assert g.frame(0.0, above(6.0), 0.0, pitch, 0.0, (1.0, 0.0, 0.0), sea_down_under_radar_m=0.4).radar_height_m == (
        pytest.approx(0.4 - radar_down)
    )


def test_marker_corners_are_a_square_of_the_given_size_tilted_about_its_centre():
    c = marker_corners_ned((1.0, 2.0, 0.5), 0.3, yaw_rad=0.4, roll_rad=0.1, pitch_rad=-0.2)
    np.testing.assert_allclose(c.mean(axis=0), (1.0, 2.0, 0.5), atol=1e-12)
    sides = np.linalg.norm(np.roll(c, -1, axis=0) - c, axis=1)
    np.testing.assert_allclose(sides, 0.3, atol=1e-12)
    assert np.ptp(c[:, 2]) > 0.01  # tilted out of the sea plane


def test_mean_edge_is_the_apparent_size_to_numpys_last_bit() -> None:
    from sim.camera_geometry import mean_edge_px

    square = np.array([[100.0, 100.0], [140.0, 100.0], [140.0, 140.0], [100.0, 140.0]])
    assert mean_edge_px(square) == 40.0
    assert mean_edge_px(np.array([[0.0, 0.0], [3.0, 4.0], [3.0, 4.0], [0.0, 0.0]])) == 2.5  # 5, 0, 5, 0
    rng = np.random.default_rng(8)
    for _ in range(500):
        c = rng.normal(size=(4, 2)) * 200.0 + 600.0
        assert mean_edge_px(c) == float(np.mean(np.linalg.norm(c - np.roll(c, -1, axis=0), axis=1)))


@pytest.mark.parametrize(
    "distortion",
    [
        (0.0, 0.0, 0.0, 0.0, 0.0),
        (-0.28, 0.07, 0.001, -0.0005, -0.01),
        (0.1, -0.2, 0.002, 0.001, 0.05, 0.01, -0.02, 0.003),
    ],
    ids=["none", "barrel", "rational"],
)
def test_the_frames_pixels_are_opencvs_projection_to_the_last_bit(distortion) -> None:
    """The frame projects in floats (no cv2 call per frame): the same pixels as ``CameraModel.project``
    (``cv2.projectPoints``), bit for bit, inside the image and far outside it, and NaN behind the camera."""
    g = GeometricCamera(CAM.model_copy(update={"distortion": distortion}), pixel_noise_std_px=0.0)
    rng = np.random.default_rng(4)
    points = np.column_stack([rng.uniform(-6.0, 6.0, (3000, 2)), rng.uniform(0.05, 25.0, 3000)])
    expected = g.model.project(points).tolist()
    assert [list(g._project(*p)) for p in points.tolist()] == expected
    assert all(math.isnan(x) for x in g._project(1.0, 1.0, -2.0) + g._project(1.0, 1.0, 0.0))
    # a whole frame: the pixels of its corners and centre as CameraModel projects them, visibility as in_image says
    for _ in range(200):
        pos = (*rng.uniform(-2.0, 2.0, 2), -rng.uniform(0.3, 12.0))
        att = rng.uniform(-0.4, 0.4, 3)
        f = g.frame(0.0, pos, *att, (*rng.uniform(-3.0, 3.0, 2), 0.0), marker_size_m=0.3)
        points_cam = (np.vstack([f.corners_ned_m, f.marker_centre_ned_m]) - f.camera_pos_ned_m) @ f.R_ned_cam
        px = g.model.project(points_cam)
        np.testing.assert_array_equal(np.vstack([f.corners_true_px, f.centre_true_px]), px)
        assert f.visible == bool(np.all(points_cam[:4, 2] > 0) and np.all(g.model.in_image(px[:4], g.margin_px)))


def test_a_level_markers_corners_are_those_of_the_rotated_square_to_the_bit() -> None:
    g = GeometricCamera(CAM, pixel_noise_std_px=0.0)
    for centre in [(1.0, 2.0, 0.5), (-3.3, 0.7, -0.12), (0.0, 0.0, 0.0)]:
        f = g.frame(0.0, above(4.0), 0.0, 0.0, 0.0, centre, marker_size_m=0.17)
        np.testing.assert_array_equal(f.corners_ned_m, marker_corners_ned(centre, 0.17))


def test_more_distortion_terms_than_the_geometric_camera_models_are_refused() -> None:
    with pytest.raises(ValueError, match="up to 8 distortion coefficients"):
        GeometricCamera(CAM.model_copy(update={"distortion": (0.0,) * 12}))
