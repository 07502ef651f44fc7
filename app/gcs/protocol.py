"""The ground-station protocol: topics and JSON payloads, version 1.

Topic tree (``<vehicle>`` is the vehicle id; ``v1`` changes only with an incompatible payload change)::

    seapick/<vehicle>/v1/cmd        ground → vehicle  QoS 1             a Command
    seapick/<vehicle>/v1/cmd/ack    vehicle → ground  QoS 1             an Ack, one per command received
    seapick/<vehicle>/v1/state      vehicle → ground  QoS 1, retained   the latest State
    seapick/<vehicle>/v1/telemetry  vehicle → ground  QoS 0, 1–5 Hz     Telemetry (latest wins)
    seapick/<vehicle>/v1/events     vehicle → ground  QoS 1             Events (state changes, detections, …)
    seapick/<vehicle>/v1/online     vehicle → ground  QoS 1, retained   ``true``; the will message sets ``false``

Commands are parsed strictly (``parse_command``): UTF-8 JSON of at most ``MAX_COMMAND_BYTES``, an object with
``cmd`` naming one of ``COMMAND_NAMES`` and an ``id`` (1–64 characters, no control characters), no other
fields than that command's, no duplicate keys, no type coercion (``"1"`` is not a number, ``1`` is not a
string). Anything else raises ``MalformedCommand``, whose text names the problem; the link answers it with
a rejected ``Ack`` carrying that text.
"""

from __future__ import annotations

import json
import math
import re
from dataclasses import dataclass
from typing import Annotated, Any, Literal, TypeAlias, cast

from pydantic import BaseModel, ConfigDict, Field, JsonValue, ValidationError

from app.errors import AppError

API_VERSION = "v1"
MAX_COMMAND_BYTES = 4096
MAX_ID_CHARS = 64
VEHICLE_ID_PATTERN = re.compile(r"[A-Za-z0-9_-]{1,64}")
COMMAND_NAMES = ("start", "abort", "hold", "resume", "rtl", "authorize_land")
CommandName: TypeAlias = Literal["start", "abort", "hold", "resume", "rtl", "authorize_land"]

_ID_PATTERN = r"^[^\x00-\x1f\x7f]+$"  # printable: an id ends up in acks, logs and terminals


class MalformedCommand(AppError):
    """Raised by ``parse_command`` for a payload that is not a valid command; ``reason`` says what is wrong.

    ``cmd_id`` and ``cmd`` are the payload's ``id`` and ``cmd`` when they could be read (else ``None``), so
    the error ack can still name the command it answers.
    """

    def __init__(self, reason: str, cmd_id: str | None = None, cmd: CommandName | None = None) -> None:
        self.reason = reason
        self.cmd_id = cmd_id
        self.cmd = cmd
        super().__init__(reason)


@dataclass(frozen=True)
class Topics:
    """The topic tree of one vehicle."""

    vehicle_id: str

    def __post_init__(self) -> None:
        if not VEHICLE_ID_PATTERN.fullmatch(self.vehicle_id):
            raise ValueError(f"vehicle id {self.vehicle_id!r}: 1–64 characters of A–Z, a–z, 0–9, '_' or '-'")

    @property
    def root(self) -> str:
        return f"seapick/{self.vehicle_id}/{API_VERSION}"

    @property
    def cmd(self) -> str:
        return f"{self.root}/cmd"

    @property
    def ack(self) -> str:
        return f"{self.root}/cmd/ack"

    @property
    def state(self) -> str:
        return f"{self.root}/state"

    @property
    def telemetry(self) -> str:
        return f"{self.root}/telemetry"

    @property
    def events(self) -> str:
        return f"{self.root}/events"

    @property
    def online(self) -> str:
        return f"{self.root}/online"


ONLINE = b"true"
OFFLINE = b"false"


# ---- commands (ground → vehicle) --------------------------------------------------------------------------


class _Command(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True, strict=True, allow_inf_nan=False)

    id: str = Field(min_length=1, max_length=MAX_ID_CHARS, pattern=_ID_PATTERN, description="command id, unique")


class Start(_Command):
    """Start the mission (from WAIT_FOR_START); optionally where to search and how far."""

    cmd: Literal["start"] = "start"
    start_ne_m: (
        tuple[Annotated[float, Field(ge=-10_000.0, le=10_000.0)], Annotated[float, Field(ge=-10_000.0, le=10_000.0)]]
        | None
    ) = Field(None, description="search start point [north, east] from home, m")
    search_radius_m: float | None = Field(None, gt=0.0, le=5_000.0, description="search area radius, m")
    drift_ne_mps: tuple[Annotated[float, Field(ge=-3.0, le=3.0)], Annotated[float, Field(ge=-3.0, le=3.0)]] | None = (
        Field(None, description="the object's expected drift [north, east] (a current forecast), m/s")
    )


class Abort(_Command):
    """Stop the mission: zero velocity, then HOLD (the mission's ABORT state)."""

    cmd: Literal["abort"] = "abort"


class Hold(_Command):
    """Pause the mission where it is."""

    cmd: Literal["hold"] = "hold"


class Resume(_Command):
    """Go on after ``hold``."""

    cmd: Literal["resume"] = "resume"


class Rtl(_Command):
    """Return to launch."""

    cmd: Literal["rtl"] = "rtl"


class AuthorizeLand(_Command):
    """Allow the descent onto the object (the thesis lands only on an operator's command)."""

    cmd: Literal["authorize_land"] = "authorize_land"


Command: TypeAlias = Start | Abort | Hold | Resume | Rtl | AuthorizeLand
_MODELS: dict[str, type[_Command]] = {
    "start": Start,
    "abort": Abort,
    "hold": Hold,
    "resume": Resume,
    "rtl": Rtl,
    "authorize_land": AuthorizeLand,
}


def parse_command(payload: bytes) -> Command:
    """The command in ``payload``; raises ``MalformedCommand`` naming the problem (nothing else escapes)."""
    if len(payload) > MAX_COMMAND_BYTES:
        raise MalformedCommand(f"payload is {len(payload)} bytes; at most {MAX_COMMAND_BYTES}")
    try:
        text = payload.decode("utf-8")
    except UnicodeDecodeError as e:
        raise MalformedCommand(f"payload is not UTF-8 text (byte {e.start})") from None
    try:
        data = json.loads(text, object_pairs_hook=_no_duplicate_keys, parse_constant=_no_constant)
    except _BadJson as e:
        raise MalformedCommand(str(e)) from None
    except (json.JSONDecodeError, RecursionError) as e:
        where = f" at line {e.lineno} column {e.colno}" if isinstance(e, json.JSONDecodeError) else ""
        raise MalformedCommand(f"not valid JSON{where}: {getattr(e, 'msg', 'nested too deeply')}") from None
    if not isinstance(data, dict):
        raise MalformedCommand(f"payload must be a JSON object, got {_json_kind(data)}")
    cmd_id = _readable_id(data.get("id"))
    name = data.get("cmd")
    if name is None:
        raise MalformedCommand(f"missing field 'cmd' (one of: {', '.join(COMMAND_NAMES)})", cmd_id)
    if not isinstance(name, str):
        raise MalformedCommand(f"cmd must be a string naming a command, got {_json_kind(name)}", cmd_id)
    if name not in _MODELS:
        raise MalformedCommand(
            f"unknown command {_shorten(json.dumps(name))} (one of: {', '.join(COMMAND_NAMES)})", cmd_id
        )
    model = _MODELS[name]
    try:
        return cast(Command, model.model_validate_json(text))
    except ValidationError as e:
        raise MalformedCommand(_describe(e, model, name), cmd_id, cast(CommandName, name)) from None


class _BadJson(ValueError):
    pass


def _no_duplicate_keys(pairs: list[tuple[str, Any]]) -> dict[str, Any]:
    out: dict[str, Any] = {}
    for key, value in pairs:
        if key in out:
            raise _BadJson(f"duplicate key {_shorten(json.dumps(key))}")
        out[key] = value
    return out


def _no_constant(name: str) -> Any:
    raise _BadJson(f"not valid JSON: {name} is not a JSON number")


def _readable_id(value: Any) -> str | None:
    """``value`` if it is an id we can echo in an ack (so the sender can match it), else ``None``."""
    if not isinstance(value, str) or not 1 <= len(value) <= MAX_ID_CHARS or not re.fullmatch(_ID_PATTERN, value):
        return None
    try:
        value.encode("utf-8")  # a lone surrogate ("\ud800") is valid JSON but cannot be sent back
    except UnicodeEncodeError:
        return None
    return value


def _json_kind(value: Any) -> str:
    if value is None:
        return "null"
    if isinstance(value, bool):
        return "a boolean"
    if isinstance(value, (int, float)):
        return "a number"
    if isinstance(value, str):
        return "a string"
    if isinstance(value, list):
        return "an array"
    return "an object"


def _shorten(text: str, limit: int = 40) -> str:
    return text if len(text) <= limit else text[: limit - 1] + "…"


def _describe(exc: ValidationError, model: type[_Command], name: str) -> str:
    """The first validation error, naming the field: ``start_ne_m.1: Input should be a valid number (got 'x')``."""
    err = exc.errors(include_url=False)[0]
    field = ".".join(str(p) for p in err["loc"]) or "payload"
    if err["type"] == "json_invalid":
        return f"not valid JSON: {err['msg'].removeprefix('Invalid JSON: ')}"
    if err["type"] == "string_pattern_mismatch":
        return f"{field}: control characters are not allowed"
    if err["type"] == "extra_forbidden":
        known = ", ".join(sorted(model.model_fields))
        return f"unknown field {_shorten(json.dumps(field))} for {name} (its fields: {known})"
    message = f"{field}: {err['msg']}"
    if err["type"] != "missing":
        got = err.get("input")
        shown = json.dumps(got) if isinstance(got, (str, int, float, bool, type(None))) else _json_kind(got)
        if isinstance(got, float) and not math.isfinite(got):
            shown = repr(got)
        message += f" (got {_shorten(shown)})"
    more = exc.error_count() - 1
    return message + (f"; and {more} more problem{'s' if more > 1 else ''}" if more else "")


# ---- vehicle → ground -------------------------------------------------------------------------------------


class _Payload(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


class Ack(_Payload):
    """The answer to one command: accepted, or rejected with the reason (also for a payload we could not read)."""

    id: str | None = Field(description="the command's id; null when the payload had no readable id")
    cmd: CommandName | None = Field(description="the command; null when the payload named no known command")
    accepted: bool
    reason: str | None = Field(None, description="why it was rejected; null when accepted")


class State(_Payload):
    """The vehicle's state as the mission sees it (retained: a new subscriber gets the latest at once)."""

    mission_state: str = Field(description="state of the mission table, e.g. WAIT_FOR_START, SEARCH")
    flight_mode: str = Field(description="the autopilot's flight mode, e.g. OFFBOARD, HOLD, POSCTL")
    armed: bool
    outcome: str | None = Field(None, description="how the mission ended (e.g. picked_up, aborted); null while running")
    last_error: str | None = Field(None, description="the last error the mission met, one line")


class TargetEstimate(_Payload):
    position_ne_m: tuple[float, float] = Field(description="estimated object position [north, east] from home, m")
    velocity_ne_mps: tuple[float, float] | None = Field(None, description="estimated drift [north, east], m/s")
    covariance_ne_m2: tuple[tuple[float, float], tuple[float, float]] = Field(
        description="2×2 covariance of position_ne_m, m²"
    )


class Battery(_Payload):
    voltage_v: float | None = Field(None, description="battery voltage, V")
    remaining_frac: float | None = Field(None, ge=0.0, le=1.0, description="remaining charge, 0..1")


class Telemetry(_Payload):
    """A snapshot at ``t_s``; sent at ``telemetry_rate_hz`` (1–5 Hz), latest wins. Non-finite numbers become null."""

    t_s: float = Field(description="time the values were measured, on the vehicle's mission clock, s")
    position_ned_m: tuple[float, float, float] = Field(description="vehicle position [north, east, down] from home, m")
    height_above_sea_m: float | None = Field(None, description="radar height above the sea surface, m")
    target: TargetEstimate | None = None
    battery: Battery | None = None


class Event(_Payload):
    """Something worth telling the operator: a state change, a detection found or lost, a calibration result."""

    t_s: float = Field(description="time it happened, on the vehicle's mission clock, s")
    kind: str = Field(min_length=1, description="e.g. state_changed, target_found, target_lost, radar_calibrated")
    fields: dict[str, JsonValue] = Field(default_factory=dict, description="what the kind carries")


def encode(payload: BaseModel) -> bytes:
    """A payload as compact UTF-8 JSON (non-finite floats as null)."""
    return payload.model_dump_json().encode()
