"""Flat-earth offsets between global points, checked against hand-computed distances."""

import math

import pytest

from app.estimators.geodesy import EARTH_RADIUS_M, ned_offset_m


def test_one_arc_minute_north_is_one_nautical_mile_ish():
    d = ned_offset_m(63.0, 9.0, 50.0, 63.0 + 1 / 60, 9.0, 50.0)
    assert d == pytest.approx((EARTH_RADIUS_M * math.radians(1 / 60), 0.0, 0.0))
    assert d[0] == pytest.approx(1853.2, abs=0.1)


def test_east_shrinks_with_cos_latitude_and_up_is_negative_down():
    d = ned_offset_m(60.0, 10.0, 50.0, 60.0, 10.001, 45.0)
    assert d[1] == pytest.approx(EARTH_RADIUS_M * math.radians(0.001) * 0.5, rel=1e-9)
    assert d[2] == pytest.approx(5.0)  # 5 m lower is +5 m down
