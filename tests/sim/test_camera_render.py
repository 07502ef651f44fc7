"""The camera renderer: truth consistent with the pixels, the exposure model, determinism."""

from __future__ import annotations

import numpy as np
import pytest

from app.sensors.camera import ExposureControls
from app.settings import CameraSettings, DetectorSettings
from sim.camera_render import CameraRenderer, Conditions, Glare
from sim.camera_render_poses import camera_pose, camera_seeing, object_pose
from sim.sea import FloatingObject, SeaConfig, SeaWorld

DISTORTED = CameraSettings(distortion=(-0.12, 0.06, 0.0005, -0.0004, 0.0))
SEA = SeaWorld(SeaConfig(sea_state=2), seed=2)
OBJECT = FloatingObject(SEA)


def scene(camera: CameraSettings, pixel: tuple[float, float], range_m: float, t_s: float = 3.0):
    obj = object_pose(OBJECT, t_s, yaw_rad=0.5)
    cam = camera_seeing(camera, obj, pixel, range_m, 0.1, -0.05, 0.2)
    assert cam is not None
    return cam, obj


@pytest.mark.parametrize("camera", [CameraSettings(), DISTORTED], ids=["pinhole", "distorted"])
def test_marker_pixels_are_where_the_truth_says(camera: CameraSettings) -> None:
    """Inside the black border (just within the true corners) it is dark; just outside them, the white plate."""
    renderer = CameraRenderer(camera, DetectorSettings(), seed=2)
    cam, obj = scene(camera, (1050.0, 180.0), 2.0)  # near a corner: where distortion is strongest
    frame = renderer.render(3.0, cam, obj, ExposureControls(exposure=20.0), Conditions(glints=0, noise_std_dn=0.0))
    corners = frame.truth.corners_px
    assert corners is not None and frame.truth.in_view
    centre = corners.mean(axis=0)
    for corner in corners:
        towards_centre = (centre - corner) / np.linalg.norm(centre - corner)
        inside = np.round(corner + 4.0 * towards_centre).astype(int)
        outside = np.round(corner - 4.0 * towards_centre).astype(int)
        assert frame.image[inside[1], inside[0]] < 40
        assert frame.image[outside[1], outside[0]] > 150


def test_exposure_and_brightness_controls_change_the_image_as_modelled() -> None:
    renderer = CameraRenderer(CameraSettings(), DetectorSettings(), seed=2)
    cam = camera_pose(np.array([0.0, 0.0, -8.0]), 0.0, 0.0, 0.0, CameraSettings())
    quiet = Conditions(glints=0, noise_std_dn=0.0)

    def mean(controls: ExposureControls, illumination: float = 1.0) -> float:
        cond = Conditions(glints=0, noise_std_dn=0.0, illumination=illumination)
        return float(renderer.render(1.0, cam, None, controls, cond).image.mean())

    base = mean(ExposureControls(32.0, 48.0))
    assert 100.0 <= base <= 140.0  # the thesis defaults expose the sea mid-band
    assert mean(ExposureControls(32.0, 24.0)) == pytest.approx(base / 2, rel=0.05)  # linear sensor
    assert mean(ExposureControls(52.0, 48.0)) == pytest.approx(base + 20.0, abs=1.0)  # brightness is an offset
    assert mean(ExposureControls(32.0, 48.0), illumination=3.0) > 200.0  # saturates
    assert renderer.render(1.0, cam, None, ExposureControls(), quiet).image.dtype == np.uint8


def test_same_seed_and_frame_render_the_same_image_and_others_differ() -> None:
    renderer = CameraRenderer(CameraSettings(), DetectorSettings(), seed=2)
    cam, obj = scene(CameraSettings(), (640.0, 480.0), 4.0)
    cond = Conditions(blur_px=3.0, glare=Glare((300.0, 300.0), 100.0))
    a = renderer.render(3.0, cam, obj, ExposureControls(), cond, frame_index=4).image
    b = renderer.render(3.0, cam, obj, ExposureControls(), cond, frame_index=4).image
    c = renderer.render(3.0, cam, obj, ExposureControls(), cond, frame_index=5).image
    assert np.array_equal(a, b) and not np.array_equal(a, c)
    assert a.shape == (960, 1280)


def test_glare_saturates_its_centre() -> None:
    renderer = CameraRenderer(CameraSettings(), DetectorSettings(), seed=2)
    cam = camera_pose(np.array([0.0, 0.0, -8.0]), 0.0, 0.0, 0.0, CameraSettings())
    cond = Conditions(glare=Glare((200.0, 700.0), 80.0), noise_std_dn=0.0)
    image = renderer.render(1.0, cam, None, ExposureControls(), cond).image
    assert image[700, 200] == 255 and image[700, 400] < 255


def test_a_marker_behind_the_camera_or_out_of_view_has_no_corners() -> None:
    renderer = CameraRenderer(CameraSettings(), DetectorSettings(), seed=2)
    obj = object_pose(OBJECT, 3.0)
    cam = camera_pose(obj.pos_ned_m + np.array([30.0, 0.0, -5.0]), 0.0, 0.0, 0.0, CameraSettings())
    frame = renderer.render(3.0, cam, obj, ExposureControls())
    assert frame.truth.corners_px is None and not frame.truth.in_view
