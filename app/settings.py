"""Settings: pydantic models loaded from a YAML profile (``settings/default.yaml``).

Every field has a range and a description that names its unit, like ArduPilot's ``@Param/@Units/@Range``
blocks. An invalid field is reported as ``ConfigError`` naming its YAML path and the allowed range.
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Any, Literal

from pydantic import BaseModel, ConfigDict, Field, StringConstraints, model_validator

from app.config_yaml import load_yaml, validate_section

SETTINGS_DIR = Path(__file__).resolve().parent.parent / "settings"


class _Model(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


class ConnectionSettings(_Model):
    url: str = Field("udpin://0.0.0.0:14540", description="MAVSDK connection URL (PX4 SITL: udpin://0.0.0.0:14540)")
    discover_timeout_s: float = Field(15.0, ge=1.0, le=120.0, description="wait for an autopilot heartbeat, s")
    ready_timeout_s: float = Field(30.0, ge=1.0, le=300.0, description="wait for position stream and home, s")
    command_retry_timeout_s: float = Field(
        20.0, ge=1.0, le=120.0, description="retry a refused arm (pre-arm checks still running) for this long, s"
    )
    setpoint_timeout_s: float = Field(
        0.2, ge=0.01, le=2.0, description="a setpoint not handed to MAVSDK within this counts as failed, s"
    )


class TelemetrySettings(_Model):
    position_rate_hz: float = Field(50.0, ge=5.0, le=100.0, description="requested LOCAL_POSITION_NED rate, Hz")
    attitude_rate_hz: float = Field(50.0, ge=5.0, le=100.0, description="requested ATTITUDE rate, Hz")
    global_position_rate_hz: float = Field(5.0, ge=1.0, le=50.0, description="requested GLOBAL_POSITION_INT rate, Hz")
    status_rate_hz: float = Field(2.0, ge=0.5, le=10.0, description="requested landed-state / home rate, Hz")
    mode_rate_hz: float = Field(
        20.0,
        ge=0.0,
        le=50.0,
        description="requested CURRENT_MODE rate (PX4 ≥ 1.15): a pilot's mode switch is seen within 1/rate "
        "instead of up to 1 s (HEARTBEAT); 0 = heartbeat only, Hz",
    )
    position_stale_s: float = Field(
        0.5, ge=0.05, le=5.0, description="position older than this is stale: the setpoint loop holds, s"
    )


class EnvelopeSettings(_Model):
    max_horizontal_speed_mps: float = Field(5.0, ge=0.1, le=20.0, description="horizontal speed limit, m/s")
    max_climb_speed_mps: float = Field(2.0, ge=0.1, le=10.0, description="vertical speed limit upwards, m/s")
    max_descent_speed_mps: float = Field(1.0, ge=0.1, le=5.0, description="vertical speed limit downwards, m/s")
    geofence_radius_m: float = Field(
        100.0, ge=5.0, le=5000.0, description="horizontal radius around home; outside it only inward motion, m"
    )
    max_height_m: float = Field(60.0, ge=2.0, le=500.0, description="height above home; above it no climbing, m")
    min_height_m: float = Field(
        1.0, ge=0.0, le=50.0, description="height above home; below it no descending in offboard, m"
    )


ParamName = Annotated[str, StringConstraints(min_length=1, max_length=16, pattern=r"^[A-Z0-9_]+$")]


class AutopilotCompensation(_Model):
    """What the position loop adds for one autopilot's velocity response (``app.offboard.guidance``)."""

    integral_gain_per_s2: float = Field(
        0.0, ge=0.0, le=10.0, description="K_I: integral action on the position error; 0: none, 1/s²"
    )
    inconsistency_tau_s: float = Field(
        0.0,
        ge=0.0,
        le=10.0,
        description="low-pass of d̂ = d(pos)/dt − vel of the autopilot's estimate, cancelled in the setpoint; 0: off, s",
    )
    velocity_error_gain: float = Field(
        0.0, ge=0.0, le=5.0, description="K_v: v_sp += K_v (v_sp − v̂) horizontally; 0: off"
    )
    velocity_lead_s: float | None = Field(
        None,
        ge=0.0,
        le=2.0,
        description="τ_lead for this autopilot (its velocity response's lag); unset: guidance.velocity_lead_s, s",
    )
    approach_speed_max_mps: float | None = Field(
        None, ge=0.1, le=15.0, description="U_a,max for this autopilot; unset: guidance.approach_speed_max_mps, m/s"
    )
    transient_distance_m: float | None = Field(
        None, ge=0.01, le=20.0, description="Δ_p̃ for this autopilot; unset: guidance.transient_distance_m, m"
    )
    precise_transient_distance_m: float | None = Field(
        None,
        ge=0.01,
        le=20.0,
        description="Δ_p̃ where the mission follows its target tightly (the pickup going down onto the object: a P "
        "gain of U_a,max/Δ); unset: the transient distance, m",
    )
    precise_velocity_lead_s: float | None = Field(
        None,
        ge=0.0,
        le=2.0,
        description="τ_lead where the mission follows its target tightly (the object's wave orbit, faster than what "
        "the lead is set for); unset: this autopilot's τ_lead, s",
    )
    precise_damping_s: float = Field(
        0.0,
        ge=0.0,
        le=1.0,
        description="τ_d where the mission follows its target tightly: guidance acts on the horizontal position "
        "error predicted τ_d ahead at the relative velocity (damping of gain U_a,max/Δ·τ_d); 0: none, s",
    )
    autopilot_params: dict[ParamName, Annotated[float, Field(allow_inf_nan=False)]] = Field(
        default_factory=dict,
        description="float parameters set on the autopilot (PARAM_SET) once it is ready, before arming; "
        "names of 1-16 characters, finite values",
    )


class GuidanceSettings(_Model):
    approach_speed_max_mps: float = Field(
        2.0, ge=0.1, le=15.0, description="U_a,max of constant-bearing guidance (thesis eq. 2.21), m/s"
    )
    transient_distance_m: float = Field(
        0.4, ge=0.01, le=20.0, description="Δ_p̃ of constant-bearing guidance (thesis eq. 2.21), m"
    )
    velocity_lead_s: float = Field(
        0.7,
        ge=0.0,
        le=2.0,
        description="target-acceleration feed-forward τ_lead, ≈ the autopilot velocity-loop lag; 0: thesis law, s",
    )
    separate_vertical: bool = Field(
        True,
        description="the law on the horizontal and the vertical error apart, each with its own κ (false: the "
        "thesis's one 3-D law, where a climb slackens the horizontal hold)",
    )
    climb_speed_max_mps: float | None = Field(
        2.0,
        ge=0.1,
        le=15.0,
        description="U_a,max of the separate vertical law when it climbs (Δ_p̃ scaled alike: the same gain near the "
        "target), where that is above the autopilot's U_a,max; unset: U_a,max, m/s",
    )
    integral_max_mps: float = Field(0.5, ge=0.0, le=3.0, description="bound of the integral term, m/s")
    integral_within_m: float = Field(
        1.0, gt=0.0, le=20.0, description="integrate the position error only this close to the target, m"
    )
    inconsistency_max_mps: float = Field(0.5, ge=0.0, le=2.0, description="bound of d̂ per axis, m/s")
    velocity_error_max_mps: float = Field(
        1.0, ge=0.0, le=5.0, description="bound of the velocity-error feedback ‖K_v (v_sp − v̂)‖, m/s"
    )
    precise_velocity_error_max_mps: float | None = Field(
        None,
        ge=0.0,
        le=5.0,
        description="that bound where the mission follows its target tightly (the pickup going down onto the "
        "object); unset: velocity_error_max_mps, m/s",
    )
    px4: AutopilotCompensation = Field(
        default_factory=lambda: AutopilotCompensation(
            integral_gain_per_s2=3.0,
            inconsistency_tau_s=0.2,
            velocity_error_gain=2.0,
            precise_transient_distance_m=0.2,
            precise_velocity_lead_s=0.4,
        ),
        description="compensation for PX4 (offboard velocity control is a velocity loop only)",
    )
    ardupilot: AutopilotCompensation = Field(
        default_factory=lambda: AutopilotCompensation(
            velocity_lead_s=0.2,
            approach_speed_max_mps=1.2,
            transient_distance_m=0.24,
            precise_transient_distance_m=0.18,
            autopilot_params={"PSC_JERK_XY": 20.0},
        ),
        description="compensation for ArduPilot (GUIDED tracks a position target of its own: only its lag is led, "
        "shortened by a higher shaping jerk limit; the approach saturates at 1.2 m/s with the same gain U_a,max/Δ "
        "as elsewhere: at 2 m/s, a target moving at ~2 m/s drove GUIDED's 2.5 m/s² shaping into a 1 m limit cycle)",
    )
    setpoint_rate_hz: float = Field(50.0, ge=20.0, le=100.0, description="offboard setpoint loop rate, Hz")
    realtime_priority: int = Field(
        10,
        ge=0,
        le=99,
        description="SCHED_FIFO priority of the event loop's thread, which wakes the setpoint loop (Linux; needs "
        "CAP_SYS_NICE or ulimit -r; refused: normal scheduling, said in the summary); 0: normal scheduling",
    )
    exit_zero_s: float = Field(
        0.5, ge=0.05, le=5.0, description="leaving offboard on our own account: zero velocity this long, then HOLD, s"
    )
    exit_timeout_s: float = Field(
        5.0, ge=0.5, le=30.0, description="the whole exit from offboard (zeros, then HOLD) is bounded by this, s"
    )
    watchdog_timeout_s: float = Field(
        0.2,
        ge=0.05,
        le=2.0,
        description="no setpoint from the event loop for this long → the watchdog thread commands zero velocity, s",
    )
    standby_rate_hz: float = Field(
        5.0,
        ge=0.0,
        le=20.0,
        description=(
            "while the pilot has control (PX4 only): zero-velocity 'offboard available' setpoints so the "
            "pilot can hand back by selecting OFFBOARD; ignored by PX4 outside OFFBOARD; 0 disables, Hz"
        ),
    )


class RunnerSettings(_Model):
    tick_rate_hz: float = Field(20.0, ge=5.0, le=100.0, description="mission table tick rate, Hz")
    mode_confirm_timeout_s: float = Field(
        5.0, ge=1.0, le=30.0, description="a commanded flight mode must show in telemetry within this, s"
    )


class CameraSettings(_Model):
    """The downward camera (thesis: oCam 1MGN, 1280×960 mono, 30 fps) and how it is mounted."""

    device: str = Field("/dev/video0", description="V4L2 device path or index")
    width_px: int = Field(1280, ge=160, le=4096, description="image width, px")
    height_px: int = Field(960, ge=120, le=4096, description="image height, px")
    fps_hz: float = Field(30.0, ge=1.0, le=120.0, description="capture rate, Hz")
    fx_px: float = Field(1000.0, ge=50.0, le=20000.0, description="focal length x, px")
    fy_px: float = Field(1000.0, ge=50.0, le=20000.0, description="focal length y, px")
    cx_px: float = Field(640.0, ge=0.0, le=4096.0, description="principal point x, px")
    cy_px: float = Field(480.0, ge=0.0, le=4096.0, description="principal point y, px")
    distortion: tuple[float, ...] = Field(
        (0.0, 0.0, 0.0, 0.0, 0.0), min_length=4, max_length=8, description="OpenCV k1 k2 p1 p2 [k3 …], unitless"
    )
    mount_roll_deg: float = Field(0.0, ge=-180.0, le=180.0, description="camera→body Euler roll, deg")
    mount_pitch_deg: float = Field(0.0, ge=-180.0, le=180.0, description="camera→body Euler pitch, deg")
    mount_yaw_deg: float = Field(90.0, ge=-180.0, le=180.0, description="camera→body Euler yaw (thesis: 90), deg")
    lever_arm_frd_m: tuple[float, float, float] = Field(
        (0.0, 0.0, 0.1), description="camera position from the body origin, forward/right/down, m"
    )
    pixel_noise_std_px: float = Field(0.5, ge=0.05, le=20.0, description="detection noise for the covariance, px")
    attitude_noise_std_deg: float = Field(
        0.0, ge=0.0, le=10.0, description="attitude error at a frame's capture time, for the covariance, deg"
    )
    auto_exposure: bool = Field(True, description="keep the mean brightness in the band (switchable at run time)")
    brightness_low: float = Field(100.0, ge=0.0, le=255.0, description="auto-exposure band low (thesis 100), grey")
    brightness_high: float = Field(140.0, ge=0.0, le=255.0, description="auto-exposure band high (thesis 140), grey")


class DetectorSettings(_Model):
    kind: Literal["aruco", "buoy"] = Field("aruco", description="marker (ArUco/AprilTag) or plain yellow buoy")
    dictionary: str = Field("DICT_4X4_50", description="cv2.aruco predefined dictionary name")
    marker_id: int = Field(7, ge=0, le=1000, description="the object's marker ID, id")
    nested_marker_ids: tuple[int, ...] = Field((), description="smaller markers nested in the big one, id")
    marker_size_m: float = Field(0.30, ge=0.01, le=5.0, description="outer marker edge length, m")
    buoy_diameter_m: float = Field(0.15, ge=0.02, le=3.0, description="buoy diameter, m")
    roi_margin: float = Field(2.0, ge=1.0, le=10.0, description="tracking window = margin × last marker size, ratio")


class RadarSettings(_Model):
    """The X4M03 and its driver; defaults are the thesis's (§4.2.2), which are also Novelda's."""

    port: str = Field("/dev/ttyACM0", description="serial device (USB CDC-ACM 03EB:6124) or a pty path")
    baudrate: int = Field(115200, ge=600, le=10_000_000, description="UART rate (ignored over USB), baud")
    tx_power: int = Field(2, ge=0, le=3, description="0 off, 1 low, 2 medium, 3 high, level")
    dac_min: int = Field(949, ge=0, le=2047, description="DAC sweep minimum, counts")
    dac_max: int = Field(1100, ge=0, le=2047, description="DAC sweep maximum, counts")
    iterations: int = Field(16, ge=1, le=255, description="sweep iterations per frame, count")
    pulses_per_step: int = Field(300, ge=1, le=65535, description="pulses per DAC step, count")
    fps_hz: float = Field(10.0, ge=1.0, le=50.0, description="frame rate requested (the X4 runs 10 as 10.032), Hz")
    frame_area_offset_m: float = Field(0.18, ge=0.0, le=1.0, description="antenna-specific range offset, m")
    frame_area_start_m: float = Field(0.4, ge=-1.0, le=9.8, description="first range wanted, m")
    frame_area_end_m: float = Field(5.0, ge=-1.0, le=9.9, description="last range wanted, m")
    downconversion: Literal[1] = Field(1, description="1 = baseband I/Q (the altitude estimator needs it), flag")
    tx_center_frequency: Literal[3, 4] = Field(3, description="3 = 7.29 GHz, 4 = 8.748 GHz, band")
    prf_div: int | None = Field(None, ge=4, le=255, description="pulse-rate divider; None keeps the board's 16")
    frame_latency_s: float | None = Field(
        None, ge=0.0, le=1.0, description="received → measured; None: half the sweep (24 ms for the thesis), s"
    )
    command_timeout_s: float = Field(2.0, ge=0.05, le=30.0, description="wait for ACK/REPLY (Novelda: 2 s), s")
    init_timeout_s: float = Field(3.0, ge=0.05, le=30.0, description="wait for x4driver_init's ACK (≥ 2 s), s")
    ready_timeout_s: float = Field(5.0, ge=0.1, le=60.0, description="ping until the device is ready, s")
    reconnect_interval_s: float = Field(1.0, ge=0.01, le=60.0, description="pause between reconnect attempts, s")
    queue_size: int = Field(4, ge=1, le=256, description="frames kept for a slow reader (oldest dropped), count")
    lever_arm_frd_m: tuple[float, float, float] = Field(
        (0.0, 0.0, 0.0), description="antenna position from the body origin, forward/right/down, m"
    )

    @model_validator(mode="after")
    def _ranges_are_ordered(self) -> RadarSettings:
        if self.dac_min >= self.dac_max:
            raise ValueError(f"dac_min ({self.dac_min}) must be below dac_max ({self.dac_max})")
        if self.frame_area_start_m >= self.frame_area_end_m:
            raise ValueError(
                f"frame_area_start_m ({self.frame_area_start_m}) must be below frame_area_end_m "
                f"({self.frame_area_end_m})"
            )
        return self

    def sweep_s(self) -> float:
        """Time one frame's sweep takes: iterations · pps · (dac_max − dac_min + 1) / PRF, PRF = 243 MHz / prf_div."""
        prf_hz = 243e6 / (self.prf_div if self.prf_div is not None else 16)
        return self.iterations * self.pulses_per_step * (self.dac_max - self.dac_min + 1) / prf_hz


class RadarAltitudeSettings(_Model):
    """The radar altitude estimator (``app/estimators/radar_altitude.py`` has the equations)."""

    method: Literal["background", "clutter_map"] = Field(
        "background", description="background map (thesis §4.2.2) or adaptive clutter map (thesis eq. 5.1)"
    )
    domain: Literal["complex", "amplitude"] = Field(
        "complex", description="maps on the complex baseband, or on amplitudes as the thesis did"
    )
    threshold_amplitude: float = Field(
        3e-4, ge=0.0, le=1.0, description="T_abs (the thesis used 0.005 with its amplitude clutter map), amplitude"
    )
    noise_factor: float = Field(6.0, ge=0.0, le=100.0, description="κ: threshold over the per-bin noise, ratio")
    gate_m: float = Field(0.15, ge=0.0, le=5.0, description="gate around the last accepted range, m")
    max_range_rate_mps: float = Field(
        2.0, ge=0.0, le=20.0, description="the gate grows by this while no candidate is accepted, m/s"
    )
    timeout_s: float = Field(1.0, ge=0.0, le=10.0, description="no accepted echo for this long → lost (thesis 1), s")
    min_range_m: float = Field(0.0, ge=0.0, le=10.0, description="nearest range searched when acquiring, m")
    clutter_alpha: float = Field(0.1, gt=0.0, lt=1.0, description="α of thesis eq. 5.1 (≈ 1 s at 10 Hz), ratio")
    peak: Literal["gaussian", "leading_edge"] = Field(
        "gaussian", description="sub-bin peak of the strongest return, or its leading edge (first return)"
    )
    pulse_sigma_m: float = Field(0.055, gt=0.0, le=1.0, description="σ of the range response (leading edge), m")
    leading_edge_fraction: float = Field(0.5, gt=0.0, lt=1.0, description="leading edge level / peak, ratio")
    tilt: Literal["specular", "boresight"] = Field(
        "specular", description="sea as a mirror (nadir return whatever the tilt) or a diffuse surface"
    )
    calibration_min_frames: int = Field(10, ge=2, le=10_000, description="background frames needed, count")
    calibration_max_change: float = Field(
        3e-4, ge=0.0, le=1.0, description="a bin changing more than this (rms) holds an echo, amplitude"
    )
    calibration_change_factor: float = Field(
        10.0, ge=1.0, le=1000.0, description="… or more than this × the quietest bins' change, ratio"
    )


class Settings(_Model):
    connection: ConnectionSettings = ConnectionSettings()
    telemetry: TelemetrySettings = TelemetrySettings()
    envelope: EnvelopeSettings = EnvelopeSettings()
    guidance: GuidanceSettings = GuidanceSettings()
    runner: RunnerSettings = RunnerSettings()
    camera: CameraSettings = CameraSettings()
    detector: DetectorSettings = DetectorSettings()
    radar: RadarSettings = RadarSettings()
    radar_altitude: RadarAltitudeSettings = RadarAltitudeSettings()
    # the ground station over MQTT (``app.gcs.config.GcsSettings`` validates it); None: no ground station, the
    # mission starts by itself
    gcs: dict[str, Any] | None = None


def load_settings(path: Path | None = None) -> Settings:
    """Load a settings profile; ``None`` loads ``settings/default.yaml``."""
    path = path or SETTINGS_DIR / "default.yaml"
    settings = validate_section(Settings, load_yaml(path), str(path))
    if settings.gcs is not None:
        from app.gcs.config import GcsSettings  # it builds on this module

        GcsSettings.from_mapping(settings.gcs, "gcs", str(path))  # a bad section fails here, naming its field
    return settings
