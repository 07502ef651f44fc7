"""The object's apparent size measures the range to it (``FixChecks.height_from_size``): below the radar's first
range the only height over the sea there is was the last radar height, held while the vehicle came down, or the
mean sea's level, which the waves move by decimetres — and a fix triangulated at a height 0.2 m too high lands
decimetres off when the object is off to the side. Checked on the geometric camera's projections."""

from __future__ import annotations

import math

import numpy as np
import pytest

from app.estimators.apparent_size import apparent_size_ratio, height_from_size, marker_size_rel_std
from app.estimators.factory import make_target_filter
from app.estimators.triangulation import SeaPlaneTriangulator
from app.messages import AttitudeEuler, PositionVelocityNed, VehicleStateNed
from app.missions.params import MissionParams
from app.missions.pickup import FixChecks, PickupEstimates
from app.settings import CameraSettings
from sim.camera_geometry import GeometricCamera

CAM = CameraSettings()


def _quat_zyx(roll: float, pitch: float, yaw: float) -> tuple[float, float, float, float]:
    cr, sr, cp, sp, cy, sy = (f(a / 2) for a in (roll, pitch, yaw) for f in (math.cos, math.sin))
    return (
        cr * cp * cy + sr * sp * sy,
        sr * cp * cy - cr * sp * sy,
        cr * sp * cy + sr * cp * sy,
        cr * cp * sy - sr * sp * cy,
    )


@pytest.mark.parametrize(
    ("height_m", "object_ne_m", "roll_deg", "used_over_true"),
    [(0.35, (0.10, 0.05), 4.0, 1.7), (0.6, (-0.15, 0.1), -8.0, 0.6), (2.0, (0.5, -0.4), 12.0, 1.3)],
)
def test_a_fix_made_at_a_wrong_height_gives_the_true_height_from_the_markers_size(
    height_m, object_ne_m, roll_deg, used_over_true
):
    """A 25 mm marker (the nested one) or 0.30 m, off to the side, the vehicle tilted: the fix is triangulated at
    the wrong height, and the ratio of its apparent size to the one expected there gives the true height to 1 %."""
    size_m = 0.025 if height_m < 1.0 else 0.30
    camera = GeometricCamera(CAM, marker_size_m=size_m, pixel_noise_std_px=0.0)
    tri = SeaPlaneTriangulator.from_settings(CAM)
    roll = math.radians(roll_deg)
    f = camera.frame(0.0, (0.0, 0.0, -height_m), roll, 0.0, 0.0, (*object_ne_m, 0.0))
    assert f.visible
    state = VehicleStateNed(0.0, (0.0, 0.0, -height_m), (0.0, 0.0, 0.0), _quat_zyx(roll, 0.0, 0.0))
    wrong = tri.fix_marker(0.0, f.corners_px, state, height_m * used_over_true)
    ratio = apparent_size_ratio(f.corners_px, wrong, tri.camera, size_m)
    h_m, std_m = height_from_size(wrong.camera_height_m, ratio, 0.01)
    print(f"true {f.camera_height_m:.4f} m, used {wrong.camera_height_m:.4f}, ratio {ratio:.3f} → {h_m:.4f} m")
    assert abs(ratio - 1.0) > 0.25  # the size check sees the wrong height …
    assert h_m == pytest.approx(f.camera_height_m, rel=0.01)  # … and the size gives the right one
    assert std_m == pytest.approx(0.01 * h_m)


def test_the_size_of_a_square_is_known_to_the_pixel_noise_over_its_edge():
    """σ of √area from corner noise, against 4000 noisy projections of a 78 px marker at 1 px of noise."""
    camera = GeometricCamera(CAM, marker_size_m=0.025, pixel_noise_std_px=1.0, seed=7)
    areas = []
    for _ in range(4000):
        f = camera.frame(0.0, (0.0, 0.0, -0.42), 0.0, 0.0, 0.0, (0.0, 0.0, 0.0))
        c = f.corners_px
        areas.append(0.5 * abs(np.dot(c[:, 0], np.roll(c[:, 1], -1)) - np.dot(c[:, 1], np.roll(c[:, 0], -1))))
    edge_px = math.sqrt(float(np.mean(areas)))
    measured = float(np.std(np.sqrt(areas))) / edge_px
    print(f"edge {edge_px:.1f} px: σ(√A)/√A {measured:.4f}, predicted {marker_size_rel_std(1.0, edge_px):.4f}")
    assert 70.0 < edge_px < 85.0
    assert measured == pytest.approx(marker_size_rel_std(1.0, edge_px), rel=0.1)
    assert marker_size_rel_std(1.0, 0.0) == math.inf


def _descending_over_a_flat_sea(
    height_from_size: bool,
    height_uncertainty_m: float = 0.625,
    ticks: int = 21,
    every: int = 3,
    roll_deg: float = 6.0,
    obj: tuple[float, float, float] = (0.12, -0.03, 0.0),
) -> tuple[list[float], PickupEstimates]:
    """The vehicle comes down at 0.5 m/s from 0.6 m over a flat sea for ``ticks`` of 0.02 s, rolled ``roll_deg``,
    the object at ``obj``, a frame every ``every`` ticks; the radar's last height (0.60 m) came at the start and is
    held (``height_max_age_s``) — its first range is above the vehicle now. Returns the errors of the fixes
    triangulated (fused or judged by the filter; not those refused), m, and the estimates."""
    # by default sea state 3 as the evaluation flies it: the waves' Hs/2 on the height
    checks = FixChecks(marker_size_m=0.30, height_uncertainty_m=height_uncertainty_m, height_from_size=height_from_size)
    m = PickupEstimates(
        SeaPlaneTriangulator.from_settings(CAM),
        make_target_filter(MissionParams(target_filter="wave", sea_state=2)),
        checks,
    )
    camera = GeometricCamera(CAM, marker_size_m=0.025, pixel_noise_std_px=0.5, seed=3)
    roll = math.radians(roll_deg)
    m.on_height(0.0, 0.60)
    errors = []
    for k in range(ticks):
        t_s = 0.02 * k
        down_m = -0.60 + 0.5 * t_s
        m.on_vehicle_sample(PositionVelocityNed(t_s, (0.0, 0.0, down_m), (0.0, 0.0, 0.5)))
        m.on_vehicle_sample(AttitudeEuler(t_s, roll, 0.0, 0.0))
        if k % every == 1 % every:
            f = camera.frame(t_s, (0.0, 0.0, down_m), roll, 0.0, 0.0, obj)
            assert f.visible
            m.on_marker(t_s, f.corners_px, 0.025)
            if m.fix_log and m.fix_log[-1][0] == t_s:
                _, n_m, e_m, _ = m.fix_log[-1]
                errors.append(math.hypot(n_m - obj[0], e_m - obj[1]))
    return errors, m


def test_low_down_the_markers_size_puts_the_fix_on_the_object_where_the_held_radar_height_does_not():
    held, held_m = _descending_over_a_flat_sea(height_from_size=False)
    sized, sized_m = _descending_over_a_flat_sea(height_from_size=True)
    print(f"fix error held radar height: {[round(e, 3) for e in held]}; from the size: {[round(e, 3) for e in sized]}")
    # while the radar's height is live (its newest ≤ radar_live_s old: the first 3 frames) it is used either way
    assert held_m.sized_fixes == 0 and sized_m.sized_fixes == 4 and len(sized) == len(held) == 7
    assert sized[:3] == held[:3]
    assert held[-1] > 0.04  # 0.2 m too high at the end
    assert max(sized[3:]) < 0.01
    assert held_m.rejected == sized_m.rejected  # the size check refused nothing either way


def test_a_nested_marker_seen_whole_far_below_the_held_radar_height_is_sized_not_refused():
    """Sea state 2 (Hs/2 = 0.25 m on the height): down at 0.5 m/s from 0.6 m to 0.24 m, the radar's 0.60 m held.
    At 0.25 m the nested marker is ~2.6 times the area the held height gives — over the size check's tolerance, and
    refused so (the MAVLink pickup went blind for its last 0.9 s). With ``height_from_size`` its size gives the
    range and the fix is fused, on the object."""
    kw = dict(height_uncertainty_m=0.25, ticks=37, every=5, roll_deg=0.0, obj=(0.03, -0.02, 0.0))
    held, held_m = _descending_over_a_flat_sea(False, **kw)  # type: ignore[arg-type]
    sized, sized_m = _descending_over_a_flat_sea(True, **kw)  # type: ignore[arg-type]
    print(f"held: {held_m.rejected}, {[round(e, 3) for e in held]}; sized: {sized_m.rejected}, {sized_m.sized_fixes}")
    # the lowest frame with the radar's height still held (0.5 s) is refused; after it the altitude over the
    # (here flat) mean sea stands in, right, and the size then agrees with it
    assert held_m.rejected.get("size", 0) == 1 and len(held) == 7
    assert sized_m.rejected.get("size", 0) == 0 and sized_m.sized_fixes >= 6 and len(sized) == 8
    assert max(sized) < 0.02


@pytest.mark.parametrize("height_from_size", [False, True])
def test_low_over_a_trough_under_the_mean_sea_the_size_still_fixes_the_object(height_from_size):
    """Over a trough the vehicle may be under the mean sea and yet over the water: here 0.1 m under it, the object
    0.45 m under it, no radar height (below its first range). No ray meets a sea above the camera — the
    altitude over the mean sea gives no fix (refused: ``no_ray``; a buoy seen 0.33 m under a sea-state-3
    vehicle was). With ``height_from_size`` the fix is triangulated at a height the uncertainty allows and its
    size gives the range: fixes on the object."""
    checks = FixChecks(
        marker_size_m=0.30, height_uncertainty_m=0.25, height_from_size=height_from_size, home_above_sea_m=0.0
    )
    m = PickupEstimates(
        SeaPlaneTriangulator.from_settings(CAM), make_target_filter(MissionParams(target_filter="wave")), checks
    )
    camera = GeometricCamera(CAM, marker_size_m=0.025, pixel_noise_std_px=0.5, seed=3)
    obj, down_m, roll = (0.05, -0.03, 0.45), 0.1, math.radians(5.0)
    for k in range(8):
        t_s = 0.066 * k
        m.on_vehicle_sample(PositionVelocityNed(t_s, (0.0, 0.0, down_m), (0.0, 0.0, 0.0)))
        m.on_vehicle_sample(AttitudeEuler(t_s, roll, 0.0, 0.0))
        f = camera.frame(t_s, (0.0, 0.0, down_m), roll, 0.0, 0.0, obj)
        assert f.visible
        m.on_marker(t_s, f.corners_px, 0.025)
    errors = [math.hypot(n_m - obj[0], e_m - obj[1]) for _, n_m, e_m, _ in m.fix_log]
    print(f"{m.rejected}, sized {m.sized_fixes}, fused {m.fixes}, errors {[round(e, 4) for e in errors]}")
    assert m.height_at(0.0)[0] < 0.0  # the altitude over the mean sea: under it
    if not height_from_size:
        assert m.rejected == {"no_ray": 8} and m.fixes == 0
    else:
        assert m.rejected.get("no_ray", 0) == 0 and m.sized_fixes == 8 and m.fixes >= 5  # (the first confirm)
        assert max(errors) < 0.02
