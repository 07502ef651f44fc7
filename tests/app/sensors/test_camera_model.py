"""Camera model: projection with distortion (thesis eqs. 2.6, 2.9) and its inverse on points."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from app.messages import CameraModel
from app.settings import CameraSettings

DIST = (-0.21, 0.06, 0.0012, -0.0008, -0.01)
MODEL = CameraModel(fx_px=1010.0, fy_px=990.0, cx_px=645.0, cy_px=470.0, distortion=DIST)


def project_by_hand(p_cam: np.ndarray, m: CameraModel) -> np.ndarray:
    """Eq. 2.6 then the radial + tangential displacement of eq. 2.9 (OpenCV's form), written out."""
    k1, k2, p1, p2, k3 = m.distortion
    x, y = p_cam[:, 0] / p_cam[:, 2], p_cam[:, 1] / p_cam[:, 2]
    r2 = x * x + y * y
    radial = 1 + k1 * r2 + k2 * r2**2 + k3 * r2**3
    xd = x * radial + 2 * p1 * x * y + p2 * (r2 + 2 * x * x)
    yd = y * radial + p1 * (r2 + 2 * y * y) + 2 * p2 * x * y
    return np.column_stack([m.fx_px * xd + m.cx_px, m.fy_px * yd + m.cy_px])


def test_project_matches_the_pinhole_and_distortion_equations():
    rng = np.random.default_rng(3)
    p = np.column_stack([rng.uniform(-3, 3, 50), rng.uniform(-2, 2, 50), rng.uniform(4, 20, 50)])
    np.testing.assert_allclose(MODEL.project(p), project_by_hand(p, MODEL), atol=1e-9)


@settings(max_examples=60, deadline=None)
@given(
    x=st.floats(-0.6, 0.6),
    y=st.floats(-0.45, 0.45),
    z=st.floats(0.5, 50.0),
)
def test_undistort_to_rays_inverts_project(x, y, z):
    p = np.array([[x * z, y * z, z]])
    ray = MODEL.undistort_to_rays(MODEL.project(p))[0]
    np.testing.assert_allclose(ray, p[0] / np.linalg.norm(p[0]), atol=1e-9)


def test_rays_are_unit_and_point_out_of_the_lens():
    rng = np.random.default_rng(4)
    px = np.column_stack([rng.uniform(0, 1280, 30), rng.uniform(0, 960, 30)])
    rays = MODEL.undistort_to_rays(px)
    assert rays.shape == (30, 3)
    np.testing.assert_allclose(np.linalg.norm(rays, axis=1), 1.0)
    assert np.all(rays[:, 2] > 0)
    np.testing.assert_allclose(MODEL.undistort_to_rays([[645.0, 470.0]]), [[0.0, 0.0, 1.0]], atol=1e-12)


def test_image_right_and_down_are_camera_x_and_y():
    rays = MODEL.undistort_to_rays([[900.0, 470.0], [645.0, 800.0]])
    assert rays[0, 0] > 0.2 and abs(rays[0, 1]) < 1e-3  # right of the principal point → +x (tangential: ~1e-4)
    assert rays[1, 1] > 0.2 and abs(rays[1, 0]) < 1e-3  # below it → +y


def test_points_behind_the_camera_project_to_nan():
    px = MODEL.project([[0.0, 0.0, -1.0], [0.1, 0.0, 2.0]])
    assert np.all(np.isnan(px[0])) and np.all(np.isfinite(px[1]))
    assert not MODEL.in_image(px)[0] and MODEL.in_image(px)[1]


def test_in_image_honours_the_margin():
    assert MODEL.in_image([[3.0, 3.0]], margin_px=2.0)[0]
    assert not MODEL.in_image([[1.0, 3.0]], margin_px=2.0)[0]
    assert not MODEL.in_image([[1279.5, 10.0]])[0]


def test_from_settings_takes_intrinsics_and_distortion():
    s = CameraSettings(fx_px=800.0, fy_px=810.0, cx_px=300.0, cy_px=200.0, distortion=(0.1, 0.0, 0.0, 0.0))
    m = CameraModel.from_settings(s)
    np.testing.assert_array_equal(m.K, [[800.0, 0, 300.0], [0, 810.0, 200.0], [0, 0, 1]])
    assert m.distortion == (0.1, 0.0, 0.0, 0.0)
    assert (m.width_px, m.height_px) == (1280, 960)


def test_empty_input_gives_empty_output():
    assert MODEL.undistort_to_rays(np.zeros((0, 2))).shape == (0, 3)
    assert MODEL.project(np.zeros((0, 3))).shape == (0, 2)


@pytest.mark.parametrize("pixel", [(0.0, 0.0), (1279.0, 959.0), (0.0, 959.0)])
def test_undistortion_converges_in_the_image_corners(pixel):
    ray = MODEL.undistort_to_rays([pixel])
    np.testing.assert_allclose(MODEL.project(ray), [pixel], atol=1e-6)
