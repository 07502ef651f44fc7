"""Mission parameters: every number a mission table may set, with its unit and allowed range."""

from __future__ import annotations

from typing import Literal

from pydantic import BaseModel, ConfigDict, Field


class MissionParams(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)

    takeoff_altitude_m: float = Field(5.0, ge=1.0, le=100.0, description="autopilot takeoff height above home, m")
    altitude_tolerance_m: float = Field(
        0.3, ge=0.05, le=2.0, description="height within this of the goal counts as reached, m"
    )
    circle_radius_m: float = Field(4.0, ge=0.5, le=50.0, description="circle target radius (thesis eq. 5.4), m")
    circle_v_reduction_s: float = Field(
        4.0, ge=0.5, le=100.0, description="circle target v_reduction: θ = t / v_reduction (thesis eq. 5.3), s"
    )
    circle_laps: float = Field(3.0, ge=0.25, le=50.0, description="laps of the circle target before landing, laps")
    tracking_settle_s: float = Field(
        10.0, ge=0.0, le=300.0, description="tracking error counts only this long after tracking starts, s"
    )
    position_lost_abort_s: float = Field(
        2.0, ge=0.2, le=30.0, description="no position sample for this long in a guided state → ABORT, s"
    )
    link_lost_s: float = Field(
        3.0, ge=0.5, le=30.0, description="no HEARTBEAT (or a dead attitude stream) for this long → link lost, s"
    )
    setpoint_failures_abort: int = Field(
        10, ge=1, le=1000, description="this many setpoints in a row failing to go out → setpoints_failing, count"
    )
    target_filter: Literal["constant_velocity", "wave"] = Field(
        "wave", description="object motion model: the thesis's constant velocity, or current + waves"
    )
    sea_state: int = Field(3, ge=0, le=5, description="expected WMO sea state (sets the wave filter's Hs, Tp), code")
