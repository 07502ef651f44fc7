"""Mission parameters: every number a mission table may set, with its unit and allowed range."""

from __future__ import annotations

from typing import Annotated

from pydantic import BaseModel, ConfigDict, Field

from app.estimators.factory import TargetFilterKind, WaveOscillators  # (the factory builds what these choose)

Pair = tuple[float, float]
Drift = Annotated[float, Field(ge=-3.0, le=3.0)]  # a drift component, m/s


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
    target_filter: TargetFilterKind = Field(
        "wave", description="object motion model: the thesis's constant velocity, or current + waves"
    )
    sea_state: int = Field(3, ge=0, le=5, description="expected WMO sea state (sets the wave filter's Hs, Tp), code")
    wave_oscillators: WaveOscillators = Field(
        "fine",
        description="wave filter: 14 narrow oscillators over 0.6-3.0 times the peak frequency (fine), or 8 at 0.7-2.3 "
        "(standard, the default before 2026-12-04), or those and two more for the short waves, on to 3.4 (wide)",
    )
    wave_elevation_std_m: float = Field(
        0.0,
        ge=0.0,
        le=1.0,
        description="wave filter: read the object's orbital velocity from the sea's elevation under the vehicle "
        "(radar), with this noise; 0 = off, m",
    )
    wave_drift_q_m2ps3: float = Field(
        1e-4,
        ge=1e-9,
        le=0.1,
        description="wave filter: how fast the object's drift may change (the current; and the autopilot's own "
        "velocity error, which moves everything the camera fixes in its frame): its mean velocity's process noise, "
        "m²/s³",
    )
    cv_q_pos_m2ps: float = Field(
        0.01, ge=1e-12, le=100.0, description="constant-velocity filter: position process noise per second, m²/s"
    )
    cv_q_vel_m2ps3: float = Field(
        0.05, ge=1e-12, le=100.0, description="constant-velocity filter: velocity process noise per second, m²/s³"
    )
    innovation_gate: bool = Field(
        True,
        description="the target filter rejects a fix whose NIS exceeds χ²(2) at p = 0.001 (false detections: keep "
        "it on); false fuses every fix, as the thesis's filter did (the evaluation's thesis baseline)",
    )

    # ---- pickup (app/missions/pickup.yaml) ------------------------------------------------------------
    calibrate_frames: int = Field(30, ge=5, le=500, description="radar frames in the background map, count")
    calibrate_margin_m: float = Field(
        2.0, ge=0.0, le=30.0, description="CALIBRATE_RADAR climbs this far above the radar's last range, m"
    )
    calibrate_attempts: int = Field(3, ge=1, le=10, description="heights tried for the background map, count")
    calibrate_climb_m: float = Field(3.0, ge=0.5, le=30.0, description="each further attempt this much higher, m")
    search_start_ne_m: Pair = Field((40.0, 20.0), description="centre of the search pattern, NE of home, m")
    search_drift_ne_mps: tuple[Drift, Drift] = Field(
        (0.0, 0.0),
        description="the object's expected drift (current and leeway, e.g. a forecast), NE, m/s: the search centre "
        "moves with it from the mission's start",
    )
    search_altitude_m: float = Field(10.0, ge=3.0, le=60.0, description="search height above home, m")
    search_object_px: float | None = Field(
        None,
        ge=5.0,
        le=200.0,
        description="search as high as the object still spans this many pixels (the detector's reach: the marker's "
        "edge, the buoy's diameter), but no higher than search_altitude_m; unset: at search_altitude_m, px",
    )
    search_speed_mps: float = Field(2.0, ge=0.2, le=10.0, description="speed along the search pattern, m/s")
    search_overlap: float = Field(0.3, ge=0.0, le=0.8, description="overlap of neighbouring camera footprints")
    search_max_radius_m: float = Field(30.0, ge=5.0, le=500.0, description="search no farther from its centre, m")
    at_point_m: float = Field(1.0, ge=0.1, le=10.0, description="this close counts as having reached a point, m")
    approach_radius_m: float = Field(1.0, ge=0.1, le=10.0, description="above the estimate within this → TRACK, m")
    track_height_m: float = Field(4.0, ge=1.0, le=30.0, description="TRACK's height above the sea (radar), m")
    track_radius_m: float = Field(0.3, ge=0.05, le=5.0, description="over the object within this to descend, m")
    fix_fresh_s: float = Field(0.5, ge=0.05, le=5.0, description="a fix younger than this is fresh, s")
    target_lost_s: float = Field(2.0, ge=0.2, le=30.0, description="no fix for this long → target lost, s")
    descend_converged_s: float = Field(
        2.0, ge=0.0, le=60.0, description="the filter converged for this long before DESCEND, s"
    )
    converged_sigma_m: float = Field(0.10, ge=0.01, le=2.0, description="filter position σ that counts as converged, m")
    descend_speed_mps: float = Field(0.5, ge=0.1, le=2.0, description="descent rate of the desired height, m/s")
    safety_height_m: float = Field(
        2.0, ge=0.5, le=20.0, description="never below this above the sea without a fresh converged fix, m"
    )
    final_height_m: float = Field(
        1.0, ge=0.0, le=10.0, description="below this over the sea, descend only right over the object, m"
    )
    final_radius_m: float = Field(
        0.1, ge=0.01, le=5.0, description="… within this of the estimate (else wait at that height), m"
    )
    final_max_speed_mps: float = Field(
        0.3, ge=0.02, le=5.0, description="… and moving with it: horizontal speed relative to it at most this, m/s"
    )
    final_abort_radius_m: float = Field(
        0.15, ge=0.02, le=5.0, description="below the final height, this far off the estimate climbs back to it, m"
    )
    final_blind_gap_s: float | None = Field(
        None,
        ge=0.05,
        le=5.0,
        description="in the final descent, no new fix for this long: the camera has lost the object low down (its "
        "view is smaller than the offset plus the tilt); go on blind only within final_radius_m of the estimate and "
        "moving with it (final_max_speed_mps), and only if it reaches touchdown_height_m at descend_speed_mps "
        "before the fix is older than fix_fresh_s, else climb back to the final height; unset: no such check, s",
    )
    final_blind_pause_s: float | None = Field(
        None,
        ge=0.02,
        le=5.0,
        description="in the final descent, no new fix for this long (shorter than final_blind_gap_s) and the water "
        "too far to reach before the fix is stale: stop going down until a fix comes (on down) or the blind gap "
        "passes (climb back, from higher and slower); unset: no pause, s",
    )
    final_start_max_rise_mps: float | None = Field(
        None,
        ge=-5.0,
        le=5.0,
        description="start the final descent only while the water under the vehicle (radar) rises no faster than "
        "this (0: only while it falls); unset: whatever the water does, m/s",
    )
    precise_max_drift_mps: float = Field(
        0.6,
        ge=0.0,
        le=5.0,
        description="DESCEND asks guidance for precision (the autopilot's precise Δ, guidance.<autopilot>) while the "
        "object drifts no faster than this; 0: never, m/s",
    )
    lean_yaw_min_tilt_deg: float | None = Field(
        None,
        ge=0.0,
        le=45.0,
        description="in APPROACH, TRACK and DESCEND, turn so that the vehicle's mean lean (wind, drift) lies along "
        "the image's wider side once it leans this much on average (app.estimators.lean); unset: the heading is "
        "held, deg",
    )
    crest_margin_m: float = Field(
        0.5, ge=0.0, le=5.0, description="the final height clears the highest recent crest by this at least, m"
    )
    crest_clearance_m: float = Field(
        0.0,
        ge=0.0,
        le=5.0,
        description="in DESCEND, not going down onto the object: the radar sees the water closer than this under "
        "the vehicle → aim higher by as much (a crest rising under it lifts it); 0: off, m",
    )
    descend_max_lead_m: float = Field(
        0.5, ge=0.1, le=5.0, description="the desired height leads the vehicle's own down by at most this, m"
    )
    final_max_lead_m: float | None = Field(
        None,
        ge=0.05,
        le=5.0,
        description="in the final descent the desired height leads the vehicle's own down by at most this (a "
        "vehicle coming down faster cannot stop above the water when it must climb back); unset: "
        "descend_max_lead_m, m",
    )
    grab_max_offset_m: float = Field(
        0.15, ge=0.02, le=2.0, description="at the water farther than this from the estimate: no grab, climb back, m"
    )
    grab_max_fall_mps: float | None = Field(
        None,
        ge=0.0,
        le=5.0,
        description="at the water by the mean sea while the water was last seen falling faster than this: no grab, "
        "climb back, m/s",
    )
    pickup_time_limit_s: float = Field(
        900.0, ge=60.0, le=7200.0, description="in the air this long without the object: RETURN (battery budget), s"
    )
    grab_fix_max_age_s: float = Field(
        0.8, ge=0.1, le=10.0, description="at the water with an older fix than this: no grab, climb back, s"
    )
    land_authorization: bool = Field(
        False, description="descend onto the object only after an operator's authorize_land (thesis), true/false"
    )
    touchdown_height_m: float = Field(0.3, ge=0.05, le=2.0, description="radar height that counts as touchdown, m")
    grab_contact_speed_mps: float = Field(
        0.05, ge=0.0, le=0.5, description="in GRAB, asked down, sinking no faster than this: on the water, m/s"
    )
    grab_contact_drop_mps: float = Field(
        0.4,
        ge=0.05,
        le=2.0,
        description="in GRAB, sinking this much slower than 0.2 s before at most: the water met it, m/s",
    )
    grab_sink_speed_mps: float = Field(
        0.8, ge=0.1, le=1.0, description="in GRAB, down onto the water at this (blind: quickly), m/s"
    )
    grab_press_m: float = Field(
        1.0, ge=0.0, le=3.0, description="in GRAB, down to the water, at most to this below the mean sea, m"
    )
    grab_contact_timeout_s: float = Field(
        3.0, ge=0.1, le=8.0, description="in GRAB, not on the water after this long: close the gripper anyway, s"
    )
    grab_abort_offset_m: float | None = Field(
        0.08,
        ge=0.02,
        le=2.0,
        description="in GRAB, not yet on the water and this far off the estimate (horizontally): no grab, climb "
        "back (null: off), m",
    )
    grab_blind_max_s: float | None = Field(
        None,
        ge=0.1,
        le=10.0,
        description="in GRAB, not yet on the water and the newest fix older than this: no grab, climb back; "
        "DESCEND goes on blind only if GRAB's sink would reach the water before (null: no such limit), s",
    )
    marker_size_m: float = Field(0.30, ge=0.02, le=3.0, description="edge of the object's marker, m")
    size_tolerance: float = Field(
        0.15, ge=0.02, le=1.0, description="apparent size within this of the expected (plus the waves' share)"
    )
    fix_height_from_size: bool = Field(
        False,
        description="where the radar measures no sea (below its first range, low over the object), triangulate a "
        "detection that passed the size check at the height its apparent size gives; false: the last radar height, "
        "held, or the altitude over the mean sea (the thesis), true/false",
    )
    confirm_frames: int = Field(3, ge=1, le=30, description="agreeing fixes before a new lock, count")
    confirm_fraction: float = Field(
        0.3, ge=0.0, le=1.0, description="the agreeing fixes are at least this share of the frames in 1 s (M of N)"
    )
    verify_height_m: float = Field(
        1.5, ge=0.5, le=10.0, description="after the grab, climb this high above the sea and look for the object, m"
    )
    verify_time_s: float = Field(
        2.0, ge=0.5, le=30.0, description="no fix of the object on the sea for this long = it is in the gripper, s"
    )
    grab_retries: int = Field(2, ge=0, le=10, description="grabs after a failed one before giving up, count")
    search_retries: int = Field(
        10,
        ge=0,
        le=100,
        description="searches around the last estimate after losing the object, before giving up and returning "
        "(PX4 PLD_MAX_SRCH, ArduPilot PLND_RET_MAX), count",
    )
    lift_altitude_m: float = Field(5.0, ge=1.0, le=60.0, description="climb to this above home after the grab, m")
    return_altitude_m: float = Field(10.0, ge=2.0, le=60.0, description="fly home at this height above home, m")
    transit_speed_mps: float = Field(
        5.0,
        ge=0.5,
        le=15.0,
        description="fly to the search area and home at up to this speed (PX4's MPC_XY_CRUISE; the envelope's "
        "horizontal limit still caps it), m/s",
    )
    transit_brake_mps2: float = Field(
        1.0,
        gt=0.0,
        le=5.0,
        description="… slowing down at this deceleration for the end of the leg (to the search speed, or to stop "
        "over home), m/s²",
    )
