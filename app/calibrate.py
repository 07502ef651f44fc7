"""``python -m app.calibrate camera IMAGES_DIR`` — intrinsics and distortion of the camera (OpenCV).

Looks for a chessboard or a ChArUco board in every image of ``IMAGES_DIR``, calibrates the pinhole model
with OpenCV's k1 k2 p1 p2 k3 distortion (thesis §2.3.2), prints the reprojection error and writes the
``camera:`` fields (``fx_px fy_px cx_px cy_px distortion width_px height_px``) into a settings YAML,
keeping everything else in that file. ``--cols``/``--rows`` count the board's *squares* (a 10×7-square
chessboard has 9×6 inner corners).

It refuses — exit code 1, the reason on stderr, nothing written — when fewer than ``--min-views`` images
show the board, when the corners of all views together cover less than ``--min-coverage`` of the image
(cells of an 8×6 grid), or when the reprojection error exceeds ``--max-rms-px``.
"""

from __future__ import annotations

import argparse
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal

import cv2
import numpy as np
import yaml
from numpy.typing import NDArray
from pydantic import ValidationError

from app.cli import OneLineParser, number, run_cli
from app.config_yaml import load_yaml
from app.errors import AppError
from app.settings import CameraSettings

IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff", ".pgm")
COVERAGE_GRID = (8, 6)  # columns × rows of image cells that the corners should reach
MIN_CHARUCO_CORNERS = 6  # a partial ChArUco view with fewer corners says too little
Board = Literal["chessboard", "charuco"]


class CalibrationRefused(AppError):
    """Raised when the images cannot give a trustworthy calibration; ``reason`` says why."""

    def __init__(self, reason: str) -> None:
        self.reason = reason
        super().__init__(reason)


@dataclass(frozen=True)
class BoardSpec:
    kind: Board
    cols: int  # squares
    rows: int  # squares
    square_m: float
    marker_m: float = 0.0  # ChArUco only
    dictionary: str = "DICT_4X4_50"  # ChArUco only


@dataclass(frozen=True)
class Views:
    image_size: tuple[int, int]  # width, height, px
    object_points: list[NDArray[np.float32]]  # per view N×3, board frame, m
    image_points: list[NDArray[np.float32]]  # per view N×2, px
    names: list[str]
    total_images: int


@dataclass(frozen=True)
class Calibration:
    image_size: tuple[int, int]
    K: NDArray[np.float64]
    distortion: tuple[float, ...]
    rms_px: float
    per_view_rms_px: list[float]
    coverage: float
    views: int

    def camera_fields(self) -> dict[str, Any]:
        """The ``camera:`` section fields of ``CameraSettings`` this calibration determines."""
        return {
            "width_px": self.image_size[0],
            "height_px": self.image_size[1],
            "fx_px": float(self.K[0, 0]),
            "fy_px": float(self.K[1, 1]),
            "cx_px": float(self.K[0, 2]),
            "cy_px": float(self.K[1, 2]),
            "distortion": [float(d) for d in self.distortion],
        }


def _detect_chessboard(gray: NDArray[Any], spec: BoardSpec) -> tuple[NDArray[Any], NDArray[Any]] | None:
    pattern = (spec.cols - 1, spec.rows - 1)  # inner corners
    flags = cv2.CALIB_CB_ADAPTIVE_THRESH | cv2.CALIB_CB_NORMALIZE_IMAGE | cv2.CALIB_CB_FAST_CHECK
    found, corners = cv2.findChessboardCorners(gray, pattern, flags=flags)
    if not found:
        return None
    criteria = (cv2.TERM_CRITERIA_EPS | cv2.TERM_CRITERIA_COUNT, 50, 1e-3)
    corners = cv2.cornerSubPix(gray, corners, (5, 5), (-1, -1), criteria)
    grid = np.mgrid[0 : pattern[0], 0 : pattern[1]].T.reshape(-1, 2) * spec.square_m
    obj = np.column_stack([grid, np.zeros(len(grid))]).astype(np.float32)
    return obj, corners.reshape(-1, 2).astype(np.float32)


def _charuco_detector(spec: BoardSpec) -> Any:
    dictionary = cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, spec.dictionary))
    board = cv2.aruco.CharucoBoard((spec.cols, spec.rows), spec.square_m, spec.marker_m, dictionary)
    return cv2.aruco.CharucoDetector(board)


def _detect_charuco(gray: NDArray[Any], detector: Any) -> tuple[NDArray[Any], NDArray[Any]] | None:
    corners, ids, _, _ = detector.detectBoard(gray)
    if ids is None or len(ids) < MIN_CHARUCO_CORNERS:
        return None
    obj, img = detector.getBoard().matchImagePoints(corners, ids)
    return obj.reshape(-1, 3).astype(np.float32), img.reshape(-1, 2).astype(np.float32)


def find_views(images_dir: Path, spec: BoardSpec) -> Views:
    """Detect the board in every image of ``images_dir``; refuses when there are no images or sizes differ."""
    paths = sorted(p for p in images_dir.iterdir() if p.suffix.lower() in IMAGE_SUFFIXES) if images_dir.is_dir() else []
    if not paths:
        raise CalibrationRefused(f"no images ({', '.join(IMAGE_SUFFIXES)}) in {images_dir}")
    detector = _charuco_detector(spec) if spec.kind == "charuco" else None
    size: tuple[int, int] | None = None
    objs, imgs, names = [], [], []
    for path in paths:
        gray = cv2.imread(str(path), cv2.IMREAD_GRAYSCALE)
        if gray is None:
            continue
        this_size = (gray.shape[1], gray.shape[0])
        if size is not None and this_size != size:
            raise CalibrationRefused(f"{path.name} is {this_size[0]}×{this_size[1]} px, the others {size[0]}×{size[1]}")
        size = this_size
        found = _detect_chessboard(gray, spec) if detector is None else _detect_charuco(gray, detector)
        if found is not None:
            objs.append(found[0])
            imgs.append(found[1])
            names.append(path.name)
    if size is None:
        raise CalibrationRefused(f"none of the {len(paths)} files in {images_dir} could be read as an image")
    return Views(size, objs, imgs, names, len(paths))


def coverage_fraction(image_points: list[NDArray[Any]], image_size: tuple[int, int]) -> float:
    """Fraction of the cells of a ``COVERAGE_GRID`` over the image that hold at least one detected corner."""
    gx, gy = COVERAGE_GRID
    hit = np.zeros((gy, gx), dtype=bool)
    if image_points:
        pts = np.vstack(image_points)
        col = np.clip((pts[:, 0] / image_size[0] * gx).astype(int), 0, gx - 1)
        row = np.clip((pts[:, 1] / image_size[1] * gy).astype(int), 0, gy - 1)
        hit[row, col] = True
    return float(hit.mean())


def calibrate(views: Views, min_views: int = 10, min_coverage: float = 0.5, max_rms_px: float = 1.0) -> Calibration:
    """Calibrate from the detected views; refuses (``CalibrationRefused``) with the reason when it should not."""
    n = len(views.image_points)
    if n < min_views:
        raise CalibrationRefused(
            f"too few views: the board was found in {n} of {views.total_images} images, need at least {min_views}"
        )
    coverage = coverage_fraction(views.image_points, views.image_size)
    if coverage < min_coverage:
        raise CalibrationRefused(
            f"poor coverage: the corners reach {100 * coverage:.0f} % of the image ({COVERAGE_GRID[0]}×"
            f"{COVERAGE_GRID[1]} cells), need at least {100 * min_coverage:.0f} % — add views with the board "
            "near the edges and corners of the image"
        )
    rms, K, dist, rvecs, tvecs = cv2.calibrateCamera(
        views.object_points, views.image_points, views.image_size, None, None
    )
    per_view = []
    for obj, img, r, t in zip(views.object_points, views.image_points, rvecs, tvecs, strict=True):
        proj, _ = cv2.projectPoints(obj, r, t, K, dist)
        per_view.append(float(np.sqrt(np.mean(np.sum((proj.reshape(-1, 2) - img) ** 2, axis=1)))))
    if rms > max_rms_px:
        worst = views.names[int(np.argmax(per_view))]
        raise CalibrationRefused(
            f"reprojection error {rms:.3f} px exceeds {max_rms_px:g} px (worst view: {worst}) — "
            "blurred images, a board that is not flat, or wrong --cols/--rows"
        )
    return Calibration(
        views.image_size,
        np.asarray(K, dtype=np.float64),
        tuple(float(d) for d in np.ravel(dist)),
        float(rms),
        per_view,
        coverage,
        n,
    )


def write_camera_yaml(path: Path, cal: Calibration) -> dict[str, Any]:
    """Merge the calibration into the ``camera:`` section of ``path`` (created if missing); returns the file's data.

    The merged section is validated as ``CameraSettings`` first; an out-of-range value is refused.
    """
    data = load_yaml(path) if path.exists() else {}
    camera = dict(data.get("camera") or {})
    camera.update(cal.camera_fields())
    try:
        CameraSettings.model_validate(camera)
    except ValidationError as e:
        raise CalibrationRefused(f"the result is not valid camera settings: {e.errors()[0]['msg']}") from e
    data["camera"] = camera
    path.parent.mkdir(parents=True, exist_ok=True)
    header = (
        f"# camera intrinsics from python -m app.calibrate: {cal.views} views, reprojection RMS {cal.rms_px:.3f} px,\n"
        f"# coverage {100 * cal.coverage:.0f} %. Fields and units: app/settings.py (CameraSettings).\n"
    )
    path.write_text(header + yaml.safe_dump(data, sort_keys=False))
    return data


def _parser() -> argparse.ArgumentParser:
    ap = OneLineParser(prog="python -m app.calibrate", description=__doc__.split("\n")[0])
    sub = ap.add_subparsers(dest="what", required=True)
    cam = sub.add_parser("camera", help="intrinsics and distortion from images of a calibration board")
    cam.add_argument("images_dir", type=Path, metavar="IMAGES_DIR")
    cam.add_argument("--board", choices=("chessboard", "charuco"), default="chessboard")
    squares = number(3, 100, "squares", int)
    edge = number(0.001, 1.0, "m")
    cam.add_argument("--cols", type=squares, default=10, help="board squares across (inner corners + 1)")
    cam.add_argument("--rows", type=squares, default=7, help="board squares down (inner corners + 1)")
    cam.add_argument("--square-m", type=edge, default=0.025, help="square edge, m")
    cam.add_argument("--marker-m", type=edge, default=None, help="ChArUco marker edge, m (default 0.75 × square)")
    cam.add_argument("--dictionary", default="DICT_4X4_50", help="ChArUco: cv2.aruco dictionary name")
    cam.add_argument("--out", type=Path, default=Path("settings/camera.yaml"), help="settings YAML to write")
    cam.add_argument(
        "--min-views", type=number(3, 10_000, "", int), default=10, help="refuse with fewer views showing the board"
    )
    cam.add_argument(
        "--min-coverage", type=number(0.0, 1.0), default=0.5, help="refuse below this fraction of image cells"
    )
    cam.add_argument(
        "--max-rms-px", type=number(0.01, 100.0, "px"), default=1.0, help="refuse above this reprojection RMS, px"
    )
    return ap


def main(argv: list[str] | None = None) -> int:
    args = _parser().parse_args(sys.argv[1:] if argv is None else argv)
    if args.board == "charuco" and not hasattr(cv2.aruco, args.dictionary):
        print(f"calibrate: unknown ArUco dictionary {args.dictionary}", file=sys.stderr)
        return 2
    marker_m = args.marker_m if args.marker_m is not None else 0.75 * args.square_m
    spec = BoardSpec(args.board, args.cols, args.rows, args.square_m, marker_m, args.dictionary)
    try:
        views = find_views(args.images_dir, spec)
        print(f"board ({args.board}, {args.cols}×{args.rows} squares) found in {len(views.names)} of "
              f"{views.total_images} images, {views.image_size[0]}×{views.image_size[1]} px")  # fmt: skip
        cal = calibrate(views, args.min_views, args.min_coverage, args.max_rms_px)
        write_camera_yaml(args.out, cal)
    except CalibrationRefused as e:
        print(f"calibrate: refused: {e.reason}", file=sys.stderr)
        return 1
    f = cal.camera_fields()
    print(f"reprojection error: RMS {cal.rms_px:.3f} px (worst view {max(cal.per_view_rms_px):.3f} px)")
    print(f"coverage: {100 * cal.coverage:.0f} % of the image")
    print(f"fx {f['fx_px']:.2f} px, fy {f['fy_px']:.2f} px, cx {f['cx_px']:.2f} px, cy {f['cy_px']:.2f} px")
    print("distortion (k1 k2 p1 p2 k3): " + " ".join(f"{d:.5f}" for d in f["distortion"]))
    print(f"wrote camera: section of {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(run_cli(main, "python -m app.calibrate"))
