"""PX4 custom_mode → FlightMode, as MAVSDK names it (checked against every PX4 mode the simulator knows)."""

from __future__ import annotations

import pytest

from app.messages import FlightMode
from app.offboard.px4_modes import px4_flight_mode
from sim.autopilot_modes import Mode, Profile


@pytest.mark.parametrize("mode", [m for m in Mode if m.profile is Profile.PX4], ids=lambda m: m.name)
def test_every_px4_mode_decodes_to_what_mavsdk_reports(mode: Mode) -> None:
    assert px4_flight_mode(mode.custom_mode) is mode.flight_mode


def test_the_bit_layout_main_16_sub_24() -> None:
    assert px4_flight_mode(3 << 16) is FlightMode.POSCTL
    assert px4_flight_mode((4 << 16) | (3 << 24)) is FlightMode.HOLD  # AUTO.LOITER
    assert px4_flight_mode((4 << 16) | (9 << 24)) is FlightMode.LAND  # AUTO.PRECLAND
    assert px4_flight_mode((4 << 16) | (77 << 24)) is FlightMode.UNKNOWN
    assert px4_flight_mode(0) is FlightMode.UNKNOWN
