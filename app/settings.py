"""Settings: pydantic models loaded from a YAML profile (``settings/default.yaml``).

Every field has a range and a description that names its unit, like ArduPilot's ``@Param/@Units/@Range``
blocks. An invalid field is reported as ``ConfigError`` naming its YAML path and the allowed range.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, Literal

import yaml
from pydantic import BaseModel, ConfigDict, Field, ValidationError

from app.errors import ConfigError

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


class TelemetrySettings(_Model):
    position_rate_hz: float = Field(50.0, ge=5.0, le=100.0, description="requested LOCAL_POSITION_NED rate, Hz")
    attitude_rate_hz: float = Field(50.0, ge=5.0, le=100.0, description="requested ATTITUDE rate, Hz")
    global_position_rate_hz: float = Field(5.0, ge=1.0, le=50.0, description="requested GLOBAL_POSITION_INT rate, Hz")
    status_rate_hz: float = Field(2.0, ge=0.5, le=10.0, description="requested landed-state / home rate, Hz")
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
    setpoint_rate_hz: float = Field(50.0, ge=20.0, le=100.0, description="offboard setpoint loop rate, Hz")
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


class Settings(_Model):
    connection: ConnectionSettings = ConnectionSettings()
    telemetry: TelemetrySettings = TelemetrySettings()
    envelope: EnvelopeSettings = EnvelopeSettings()
    guidance: GuidanceSettings = GuidanceSettings()
    runner: RunnerSettings = RunnerSettings()
    camera: CameraSettings = CameraSettings()
    detector: DetectorSettings = DetectorSettings()


def format_validation_error(source: str, exc: ValidationError, model: type[BaseModel]) -> ConfigError:
    """The first error of ``exc`` as a ``ConfigError`` naming the YAML path and the allowed range."""
    err = exc.errors()[0]
    path = ".".join(str(p) for p in err["loc"])
    got = err.get("input")
    message = err["msg"]
    allowed = _allowed_range(model, [str(p) for p in err["loc"]])
    if err["type"] == "extra_forbidden":
        known = _known_fields(model, [str(p) for p in err["loc"][:-1]])
        message = "unknown field" + (f"; known fields: {', '.join(known)}" if known else "")
    else:
        message = f"{message} (got {got!r})"
        if allowed:
            message += f"; allowed {allowed}"
    return ConfigError(source, path, message)


def _field_info(model: type[BaseModel], loc: list[str]) -> Any:
    current: Any = model
    info = None
    for key in loc:
        fields = getattr(current, "model_fields", None)
        if not fields or key not in fields:
            return None
        info = fields[key]
        current = info.annotation
    return info


def _known_fields(model: type[BaseModel], loc: list[str]) -> list[str]:
    current: Any = model
    for key in loc:
        fields = getattr(current, "model_fields", None)
        if not fields or key not in fields:
            return []
        current = fields[key].annotation
    return sorted(getattr(current, "model_fields", {}))


def _allowed_range(model: type[BaseModel], loc: list[str]) -> str:
    info = _field_info(model, loc)
    if info is None:
        return ""
    lo = hi = None
    for m in info.metadata:
        lo = getattr(m, "ge", lo) if getattr(m, "ge", None) is not None else lo
        lo = getattr(m, "gt", lo) if getattr(m, "gt", None) is not None else lo
        hi = getattr(m, "le", hi) if getattr(m, "le", None) is not None else hi
        hi = getattr(m, "lt", hi) if getattr(m, "lt", None) is not None else hi
    if lo is None and hi is None:
        return ""
    unit = ""
    if info.description and "," in info.description:
        unit = " " + info.description.rsplit(",", 1)[1].strip()
    return f"{'' if lo is None else lo}..{'' if hi is None else hi}{unit}"


def load_yaml(path: Path) -> dict[str, Any]:
    try:
        data = yaml.safe_load(path.read_text()) or {}
    except FileNotFoundError as e:
        raise ConfigError(str(path), "", "file not found") from e
    except yaml.YAMLError as e:
        raise ConfigError(str(path), "", f"not valid YAML: {e}") from e
    if not isinstance(data, dict):
        raise ConfigError(str(path), "", "top level must be a mapping")
    return data


def load_settings(path: Path | None = None) -> Settings:
    """Load a settings profile; ``None`` loads ``settings/default.yaml``."""
    path = path or SETTINGS_DIR / "default.yaml"
    data = load_yaml(path)
    try:
        return Settings.model_validate(data)
    except ValidationError as e:
        raise format_validation_error(str(path), e, Settings) from e
