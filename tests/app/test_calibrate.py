"""Camera calibration CLI on synthetic board images rendered through known intrinsics and distortion."""

from __future__ import annotations

import math
from pathlib import Path

import cv2
import numpy as np
import pytest
import yaml

from app.calibrate import COVERAGE_GRID, coverage_fraction, main
from app.estimators.rotations import euler_zyx_to_matrix
from app.settings import load_settings

W, H = 640, 480
K_TRUE = np.array([[600.0, 0.0, 322.0], [0.0, 610.0, 236.0], [0.0, 0.0, 1.0]])
D_TRUE = np.array([-0.12, 0.03, 0.0005, -0.0003, 0.0])
COLS, ROWS, SQUARE_M, TEX_PX = 10, 7, 0.03, 40  # board squares, edge, texture px per square


def chessboard_texture() -> np.ndarray:
    """A COLS×ROWS chessboard with a one-square white margin."""
    tex = np.full(((ROWS + 2) * TEX_PX, (COLS + 2) * TEX_PX), 255, np.uint8)
    for r in range(ROWS):
        for c in range(COLS):
            if (r + c) % 2 == 0:
                tex[(r + 1) * TEX_PX : (r + 2) * TEX_PX, (c + 1) * TEX_PX : (c + 2) * TEX_PX] = 0
    return tex


def charuco_texture() -> np.ndarray:
    board = cv2.aruco.CharucoBoard(
        (COLS, ROWS), SQUARE_M, 0.75 * SQUARE_M, cv2.aruco.getPredefinedDictionary(cv2.aruco.DICT_4X4_50)
    )
    return board.generateImage(((COLS + 2) * TEX_PX, (ROWS + 2) * TEX_PX), marginSize=TEX_PX)


class Renderer:
    """Board texture → distorted image: each output pixel is undistorted (known K, D), then mapped back onto
    the board plane through the view's homography K [r1 r2 t]."""

    def __init__(self, texture: np.ndarray, seed: int) -> None:
        self.tex = texture
        uu, vv = np.meshgrid(np.arange(W, dtype=np.float64), np.arange(H, dtype=np.float64))
        grid = np.column_stack([uu.ravel(), vv.ravel()]).reshape(-1, 1, 2)
        criteria = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 50, 1e-10)
        self.ideal = cv2.undistortPointsIter(grid, K_TRUE, D_TRUE, np.eye(3), K_TRUE, criteria)  # N×1×2
        m = SQUARE_M / TEX_PX  # metres per texture pixel
        w_m, h_m = texture.shape[1] * m, texture.shape[0] * m
        self.S = np.array([[m, 0.0, 0.5 * m - w_m / 2], [0.0, m, 0.5 * m - h_m / 2], [0.0, 0.0, 1.0]])
        self.rng = np.random.default_rng(seed)

    def view(self, u: float, v: float, distance_m: float, tilt_deg: float = 25.0) -> np.ndarray:
        a, b = np.radians(self.rng.uniform(-tilt_deg, tilt_deg, 2))
        R = euler_zyx_to_matrix(a, b, math.radians(self.rng.uniform(-20, 20)))
        t = distance_m * np.linalg.solve(K_TRUE, [u, v, 1.0])  # board centre on pixel (u, v)
        H_tex = K_TRUE @ np.column_stack([R[:, 0], R[:, 1], t]) @ self.S
        tex_xy = cv2.perspectiveTransform(self.ideal, np.linalg.inv(H_tex)).reshape(H, W, 2).astype(np.float32)
        img = cv2.remap(self.tex, tex_xy, None, cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT, borderValue=128)
        img = cv2.GaussianBlur(img, (0, 0), 0.7)
        return np.clip(img + self.rng.normal(0, 2.0, img.shape), 0, 255).astype(np.uint8)


SPREAD = [(u, v) for u in (170, 320, 470) for v in (130, 240, 350)] + [(240, 180), (400, 300), (320, 240)]


def write_views(directory: Path, texture: np.ndarray, centres, distance_m: float = 0.75) -> Path:
    directory.mkdir()
    r = Renderer(texture, seed=len(centres))
    for i, (u, v) in enumerate(centres):
        cv2.imwrite(str(directory / f"view{i:02d}.png"), r.view(u, v, distance_m))
    return directory


@pytest.fixture(scope="module")
def image_sets(tmp_path_factory):
    root = tmp_path_factory.mktemp("calib")
    tex = chessboard_texture()
    return {
        "good": write_views(root / "good", tex, SPREAD),
        "few": write_views(root / "few", tex, SPREAD[:6]),
        "corner": write_views(root / "corner", tex, [(150 + 5 * k, 110 + 3 * k) for k in range(12)], 1.2),
        "charuco": write_views(root / "charuco", charuco_texture(), SPREAD),
    }


def run(argv, capsys):
    code = main(argv)
    out = capsys.readouterr()
    return code, out.out, out.err


def assert_recovered(camera: dict) -> None:
    assert camera["fx_px"] == pytest.approx(K_TRUE[0, 0], rel=0.02)
    assert camera["fy_px"] == pytest.approx(K_TRUE[1, 1], rel=0.02)
    assert camera["cx_px"] == pytest.approx(K_TRUE[0, 2], rel=0.02)
    assert camera["cy_px"] == pytest.approx(K_TRUE[1, 2], rel=0.02)
    assert camera["distortion"][0] == pytest.approx(D_TRUE[0], abs=0.03)  # k1: barrel is found
    assert (camera["width_px"], camera["height_px"]) == (W, H)


def test_chessboard_views_recover_the_true_intrinsics_and_write_loadable_settings(image_sets, tmp_path, capsys):
    out = tmp_path / "camera.yaml"
    code, stdout, _ = run(["camera", str(image_sets["good"]), "--cols", "10", "--rows", "7", "--square-m", "0.03",
                           "--out", str(out)], capsys)  # fmt: skip
    assert code == 0
    assert "found in 12 of 12 images" in stdout and "reprojection error: RMS" in stdout
    rms = float(stdout.split("RMS ")[1].split(" px")[0])
    assert rms < 0.3
    assert_recovered(yaml.safe_load(out.read_text())["camera"])
    s = load_settings(out)  # a valid settings profile: the camera section, other sections at defaults
    assert s.camera.fx_px == pytest.approx(600.0, rel=0.02) and s.camera.width_px == W


def test_an_existing_settings_file_keeps_its_other_fields(image_sets, tmp_path, capsys):
    out = tmp_path / "profile.yaml"
    out.write_text("camera:\n  mount_yaw_deg: -90\n  device: /dev/video2\nrunner:\n  tick_rate_hz: 25\n")
    code, _, _ = run(["camera", str(image_sets["good"]), "--out", str(out)], capsys)
    assert code == 0
    s = load_settings(out)
    assert s.camera.mount_yaw_deg == -90 and s.camera.device == "/dev/video2" and s.runner.tick_rate_hz == 25
    assert s.camera.cx_px == pytest.approx(322.0, rel=0.02)


def test_charuco_views_recover_the_true_intrinsics(image_sets, tmp_path, capsys):
    out = tmp_path / "camera.yaml"
    code, _, err = run(["camera", str(image_sets["charuco"]), "--board", "charuco", "--square-m", "0.03",
                        "--out", str(out)], capsys)  # fmt: skip
    assert code == 0, err
    assert_recovered(yaml.safe_load(out.read_text())["camera"])


def test_too_few_views_are_refused_with_the_reason_and_nothing_is_written(image_sets, tmp_path, capsys):
    out = tmp_path / "camera.yaml"
    code, _, err = run(["camera", str(image_sets["few"]), "--out", str(out)], capsys)
    assert code == 1
    assert "too few views" in err and "6 of 6 images" in err and "at least 10" in err
    assert not out.exists()


def test_views_bunched_in_one_corner_are_refused_for_poor_coverage(image_sets, tmp_path, capsys):
    out = tmp_path / "camera.yaml"
    code, stdout, err = run(["camera", str(image_sets["corner"]), "--out", str(out)], capsys)
    assert "found in 12 of 12 images" in stdout  # enough views …
    assert code == 1 and "poor coverage" in err  # … but all in one place
    assert not out.exists()


def test_a_wrong_board_size_finds_no_views(image_sets, tmp_path, capsys):
    code, stdout, err = run(["camera", str(image_sets["few"]), "--cols", "8", "--rows", "6",
                             "--out", str(tmp_path / "c.yaml")], capsys)  # fmt: skip
    assert code == 1 and "found in 0 of 6 images" in stdout and "too few views" in err


def test_an_empty_directory_is_refused(tmp_path, capsys):
    code, _, err = run(["camera", str(tmp_path), "--out", str(tmp_path / "c.yaml")], capsys)
    assert code == 1 and "no images" in err


def test_coverage_counts_grid_cells_reached_by_corners():
    gx, gy = COVERAGE_GRID
    centres = [np.array([[(i + 0.5) * W / gx, (j + 0.5) * H / gy]]) for i in range(gx) for j in range(gy)]
    assert coverage_fraction(centres, (W, H)) == 1.0
    assert coverage_fraction(centres[:12], (W, H)) == pytest.approx(12 / (gx * gy))
    assert coverage_fraction([], (W, H)) == 0.0
