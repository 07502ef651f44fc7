"""The real marker detector through rendered descents from 4 m to 0.3 m over sea state 2 (``sim.detect_study``).

Bounds are what ``python -m sim.detect_study --seeds 20 [--oscillation-m 0.08]`` measured, with margin. The
ringing vehicle (tilt p50 ~18°, up to ~30°, like the PX4 run of the end-to-end pickup) pins the fixes: a
marker cut by the image border no longer hides the whole nested one inside it, and a small marker turned 45°
is no longer dropped by the size bound; before them it lost 4–11 % of the frames a perfect detector sees.
"""

from __future__ import annotations

import pytest

from sim.detect_study import DescentConfig, print_table, study

SEEDS = range(5)
BANDS = ("4-3", "3-2", "2-1.5", "1.5-1", "1-0.6", "0.6-0.3")


def bands(result: dict) -> dict[str, dict]:
    print_table(result)
    rows = {r["band_m"]: r for r in result["bands"]}
    assert tuple(rows) == BANDS
    return rows


@pytest.fixture(scope="module")
def following() -> dict[str, dict]:
    return bands(study(SEEDS))


@pytest.fixture(scope="module")
def ringing() -> dict[str, dict]:
    return bands(study(SEEDS, DescentConfig(oscillation_m=0.08)))


def test_a_vehicle_following_the_object_keeps_the_marker_to_the_last_half_metre(following) -> None:
    """Tilt ≤ ~13°, offset ≤ 0.2 m: every frame from 4 m to 0.6 m, then only the frames out of view are lost."""
    for band in BANDS[:-1]:
        assert following[band]["rate"] >= 0.99 and following[band]["longest_gap_s"] <= 0.15, band
    last = following["0.6-0.3"]
    assert last["rate"] >= 0.85 and last["longest_gap_s"] <= 0.6
    assert set(last["misses_by_class"]) <= {"out of view"}
    assert following["0.6-0.3"]["found_ids"].keys() >= {"8"}  # the nested marker holds the lock near the water
    for band in BANDS:
        assert following[band]["rate_decodable"] >= 0.99, band
        assert following[band]["corner_error_max_px"] <= 2.0, band


def test_a_ringing_vehicle_loses_only_what_is_out_of_view_or_too_small(ringing) -> None:
    """Tilt up to ~30°: the marker leaves the image (the gaps), but every frame where it is decodable is found."""
    # How much of the time the marker is in view at all is the ringing's geometry over this sea, not the detector's
    # doing. Since 2026-12-03 the current carries the waves (``sim.sea``): the same five descents meet the object
    # in another phase, and the 1.5-1 m and 0.6-0.3 m bands hold it 0.747 and 0.200 of the time (0.770 and 0.356
    # over 20 seeds; 0.833 and 0.263 on the sea before), every miss out of view (below: every decodable frame found)
    min_rate = {"4-3": 0.85, "3-2": 0.78, "2-1.5": 0.85, "1.5-1": 0.70, "1-0.6": 0.55, "0.6-0.3": 0.15}
    max_gap_s = {"4-3": 0.5, "3-2": 0.5, "2-1.5": 0.5, "1.5-1": 0.5, "1-0.6": 0.6, "0.6-0.3": 0.8}
    for band in BANDS:
        row = ringing[band]
        assert row["rate"] >= min_rate[band] and row["longest_gap_s"] <= max_gap_s[band], band
        assert row["rate_decodable"] >= 0.98, band
        assert row["corner_error_max_px"] <= 3.0, band
