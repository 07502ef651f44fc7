"""A run as Foxglove channels: the event log's records (and the simulator's truth) mapped onto Foxglove schemas, written
to ``run.mcap`` (``write_mcap``) or served live (``app.foxglove_live``) — one mapping for both.

The event log stays the source of truth: ``run.mcap`` is made from ``events.jsonl`` and, when the simulator wrote
one, ``sim_state.jsonl`` (its ``t_s`` counts from ``boot_monotonic_s`` in its ``start`` record, on the app's clock).
Every message's log time, and its ``timestamp`` field where the schema has one, is the record's ``t_s`` (loop clock)
in nanoseconds: a virtual-time evaluation run starts near 0 s, a flight at the companion computer's monotonic time.

Frames: the records are NED about home and the messages keep them so, in frame ``ned`` (x north, y east, z down).
``/tf`` places ``ned`` in ``world`` (x north, y west, z up: the 3D panel's grid is the level sea and up is up) by a
half turn about north, and the vehicle's body frame ``vehicle`` (forward, right, down) in ``ned``. Pick ``world`` as
the 3D panel's display frame.

=====================  ========================  =================================================================
topic                  schema                    from
=====================  ========================  =================================================================
/tf                    foxglove.FrameTransforms  ``pickup``: world→ned (repeated, for late live clients), ned→vehicle
/vehicle/pose          foxglove.PoseInFrame      ``pickup``: the vehicle's own estimate (position; attitude if logged)
/vehicle/truth         foxglove.PoseInFrame      simulator ``truth`` (position; attitude from a MAVLink flight)
/object/truth          foxglove.PoseInFrame      simulator ``object``
/object/estimate       foxglove.PoseInFrame      ``pickup``: the target filter's estimate
/object/covariance     foxglove.SceneUpdate      ``pickup``: the estimate's horizontal 2σ ellipse
/detections            foxglove.SceneUpdate      ``fix``: each triangulated fix, coloured by what the filter did
/setpoint              JSON seapick.Setpoint     ``setpoint``: every decision of the setpoint loop
/radar/height          JSON seapick.RadarHeight  ``pickup``: the height above the sea
/radar/profile         JSON seapick.RadarProfile ``radar_profile``: the range axis, ``amplitude`` per bin (dB)
/camera/image          foxglove.CompressedImage  ``camera``: ``jpeg``, a JPEG file's path relative to the run dir
/mission/state         JSON seapick.MissionState ``state``
/log                   foxglove.Log              ``state``, ``command``, ``run``, ``vehicle``, ``gcs``; simulator grabs
=====================  ========================  =================================================================

A channel is created with its first message, so a file lists only the topics its run has.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import foxglove
from foxglove import channels as fc
from foxglove import messages as fm

from app.estimators.rotations import quat_from_euler_zyx
from app.report import read_jsonl

MCAP_NAME = "run.mcap"  # sim.evaluate_report links it by this name
ELLIPSE_SIGMAS = 2.0  # /object/covariance: the ellipse's semi-axes, standard deviations
ELLIPSE_THICKNESS_M = 0.02
FIX_LIFETIME_S = 3.0  # a fix stays on /detections this long
FIX_SIZE_M = 0.15
FIX_COLOURS = {"fused": (0.1, 0.8, 0.2), "confirming": (1.0, 0.8, 0.0)}  # any other result: a rejection, red
REJECTED = (0.9, 0.1, 0.1)
OK_RESULTS = {"ok"}  # a command with another result is logged as a warning
WORLD_TO_NED = fm.Quaternion(x=1.0, y=0.0, z=0.0, w=0.0)  # a half turn about north: z down → z up

JsonSchema = dict[str, Any]


def _schema(title: str, **properties: Any) -> JsonSchema:
    return {"title": title, "type": "object", "properties": properties}


_NUM = {"type": "number"}
_VEC3 = {"type": "array", "items": _NUM, "minItems": 3, "maxItems": 3}
_TEXT = {"type": "string"}
JSON_SCHEMAS: dict[str, JsonSchema] = {
    "/setpoint": _schema(
        "seapick.Setpoint",
        decision=_TEXT,
        source=_TEXT,
        vel=_VEC3 | {"description": "velocity setpoint sent, NED, m/s"},
        desired=_VEC3 | {"description": "what guidance asked for before the envelope, NED, m/s"},
        limits={"type": "array", "items": _TEXT},
        err_m=_NUM,
    ),
    "/radar/height": _schema("seapick.RadarHeight", height_above_sea_m=_NUM),
    "/radar/profile": _schema(
        "seapick.RadarProfile",
        range_start_m=_NUM | {"description": "range of the first bin, m"},
        range_step_m=_NUM | {"description": "range between bins, m"},
        amplitude={
            "type": "array",
            "items": _NUM,
            "description": "per bin, dB: 20·log10 |I + jQ| re one unit of the X4's baseband floats",
        },
    ),
    "/mission/state": _schema("seapick.MissionState", state=_TEXT, previous=_TEXT, reason=_TEXT),
}
TYPED_CHANNELS: dict[str, Callable[..., Any]] = {
    "/tf": fc.FrameTransformsChannel,
    "/vehicle/pose": fc.PoseInFrameChannel,
    "/vehicle/truth": fc.PoseInFrameChannel,
    "/object/truth": fc.PoseInFrameChannel,
    "/object/estimate": fc.PoseInFrameChannel,
    "/object/covariance": fc.SceneUpdateChannel,
    "/detections": fc.SceneUpdateChannel,
    "/camera/image": fc.CompressedImageChannel,
    "/log": fc.LogChannel,
}
LOG_KINDS = ("state", "command", "run", "vehicle", "gcs")
EVENT_KINDS = frozenset({"pickup", "fix", "setpoint", "radar_profile", "camera", *LOG_KINDS})  # what maps to a topic

Message = tuple[str, Any]  # (topic, a foxglove.messages object or a JSON dict)


def time_ns(t_s: float) -> int:
    return round(t_s * 1e9)


def stamp(t_s: float) -> fm.Timestamp:
    sec, nsec = divmod(time_ns(t_s), 1_000_000_000)
    return fm.Timestamp(sec, nsec)


def _vector(v: list[float]) -> fm.Vector3:
    return fm.Vector3(x=v[0], y=v[1], z=v[2])


def _attitude(rpy_rad: list[float] | None) -> fm.Quaternion:
    """The body (FRD) in NED from roll, pitch, yaw (ZYX); none logged: level, facing north."""
    w, x, y, z = quat_from_euler_zyx(*rpy_rad) if rpy_rad is not None else (1.0, 0.0, 0.0, 0.0)
    return fm.Quaternion(x=x, y=y, z=z, w=w)


def _pose(t_s: float, pos_ned_m: list[float], rpy_rad: list[float] | None = None) -> fm.PoseInFrame:
    pose = fm.Pose(position=_vector(pos_ned_m), orientation=_attitude(rpy_rad))
    return fm.PoseInFrame(timestamp=stamp(t_s), frame_id="ned", pose=pose)


def _yaw(angle_rad: float) -> fm.Quaternion:
    return fm.Quaternion(x=0.0, y=0.0, z=math.sin(angle_rad / 2), w=math.cos(angle_rad / 2))


def covariance_ellipse(t_s: float, pos_ned_m: list[float], sigma_ne_m: list[float], rho_ne: float) -> fm.SceneUpdate:
    """The horizontal covariance (standard deviations north and east, their correlation) as a flat ellipsoid,
    ``ELLIPSE_SIGMAS`` standard deviations each way along its principal axes."""
    a, b, c = sigma_ne_m[0] ** 2, rho_ne * sigma_ne_m[0] * sigma_ne_m[1], sigma_ne_m[1] ** 2
    # principal axes of [[a, b], [b, c]]: λ = (a+c)/2 ± √(((a−c)/2)² + b²), the major one at ½·atan2(2b, a−c) from north
    mid, half = (a + c) / 2, math.hypot((a - c) / 2, b)
    major_m, minor_m = (ELLIPSE_SIGMAS * math.sqrt(max(lam, 0.0)) for lam in (mid + half, mid - half))
    angle_rad = 0.5 * math.atan2(2 * b, a - c)
    sphere = fm.SpherePrimitive(
        pose=fm.Pose(position=_vector(pos_ned_m), orientation=_yaw(angle_rad)),
        size=fm.Vector3(x=2 * major_m, y=2 * minor_m, z=ELLIPSE_THICKNESS_M),
        color=fm.Color(r=1.0, g=0.5, b=0.0, a=0.35),
    )
    entity = fm.SceneEntity(timestamp=stamp(t_s), frame_id="ned", id="estimate", spheres=[sphere])
    return fm.SceneUpdate(entities=[entity])


class RecordMapper:
    """Records in, (topic, message) pairs out. Keeps two things between records: the estimate's height (a fix has
    only north and east: it is drawn on the sea where the estimate is) and the run directory (camera files)."""

    def __init__(self, run_dir: Path | None = None) -> None:
        self.run_dir = run_dir
        self.sea_down_m = 0.0
        self.fixes = 0
        self.handlers: dict[str, Callable[[float, dict[str, Any]], list[Message]]] = {
            "pickup": self._pickup, "fix": self._fix, "setpoint": self._setpoint, "state": self._state,
            "radar_profile": self._radar_profile, "camera": self._camera,
            "sim.object": self._sim_object, "sim.truth": self._sim_truth, "sim.grab": self._sim_grab,
        }  # fmt: skip

    def messages(self, r: dict[str, Any]) -> list[Message]:
        kind = r.get("kind")
        handler = self.handlers.get(kind) if isinstance(kind, str) else None
        out = handler(r["t_s"], r) if handler is not None else []
        if kind in LOG_KINDS:
            out.append(("/log", _log_line(r)))
        return out

    def _pickup(self, t_s: float, r: dict[str, Any]) -> list[Message]:
        rpy, vehicle = r.get("vehicle_rpy_rad"), [*r["vehicle_ne_m"], r.get("vehicle_down_m", 0.0)]
        world = fm.FrameTransform(timestamp=stamp(t_s), parent_frame_id="world", child_frame_id="ned",
                                  rotation=WORLD_TO_NED)  # fmt: skip
        body = fm.FrameTransform(timestamp=stamp(t_s), parent_frame_id="ned", child_frame_id="vehicle",
                                 translation=_vector(vehicle), rotation=_attitude(rpy))  # fmt: skip
        out: list[Message] = [
            ("/tf", fm.FrameTransforms(transforms=[world, body])),
            ("/vehicle/pose", _pose(t_s, vehicle, rpy)),
        ]
        if r.get("estimate_ne_m") is not None:
            if r.get("estimate_down_m") is not None:
                self.sea_down_m = r["estimate_down_m"]
            estimate = [*r["estimate_ne_m"], self.sea_down_m]
            out.append(("/object/estimate", _pose(t_s, estimate)))
            if r.get("estimate_sigma_ne_m") is not None:
                ellipse = covariance_ellipse(t_s, estimate, r["estimate_sigma_ne_m"], r.get("estimate_rho_ne") or 0.0)
                out.append(("/object/covariance", ellipse))
        if r.get("height_above_sea_m") is not None:
            out.append(("/radar/height", {"height_above_sea_m": r["height_above_sea_m"]}))
        return out

    def _fix(self, t_s: float, r: dict[str, Any]) -> list[Message]:
        self.fixes += 1
        red, green, blue = FIX_COLOURS.get(r.get("result", ""), REJECTED)
        sphere = fm.SpherePrimitive(
            pose=fm.Pose(position=_vector([*r["ne_m"], self.sea_down_m])),
            size=fm.Vector3(x=FIX_SIZE_M, y=FIX_SIZE_M, z=FIX_SIZE_M),
            color=fm.Color(r=red, g=green, b=blue, a=0.9),
        )
        entity = fm.SceneEntity(
            timestamp=stamp(t_s), frame_id="ned", id=f"fix/{self.fixes}", spheres=[sphere],
            lifetime=fm.Duration(*divmod(time_ns(FIX_LIFETIME_S), 1_000_000_000)),
            metadata=[fm.KeyValuePair(key="result", value=str(r.get("result")))],
        )  # fmt: skip
        return [("/detections", fm.SceneUpdate(entities=[entity]))]

    def _setpoint(self, t_s: float, r: dict[str, Any]) -> list[Message]:
        return [("/setpoint", {k: v for k, v in r.items() if k not in ("t_s", "kind")})]

    def _radar_profile(self, t_s: float, r: dict[str, Any]) -> list[Message]:
        keys = ("range_start_m", "range_step_m", "amplitude")
        return [("/radar/profile", {k: r[k] for k in keys})]

    def _camera(self, t_s: float, r: dict[str, Any]) -> list[Message]:
        if self.run_dir is None:
            return []
        data = (self.run_dir / r["jpeg"]).read_bytes()
        return [
            ("/camera/image", fm.CompressedImage(timestamp=stamp(t_s), frame_id="camera", data=data, format="jpeg"))
        ]

    def _state(self, t_s: float, r: dict[str, Any]) -> list[Message]:
        return [("/mission/state", {"state": r["to"], "previous": r.get("from") or "", "reason": r.get("reason", "")})]

    def _sim_object(self, t_s: float, r: dict[str, Any]) -> list[Message]:
        return [("/object/truth", _pose(t_s, r["pos_ned_m"]))]

    def _sim_truth(self, t_s: float, r: dict[str, Any]) -> list[Message]:
        return [("/vehicle/truth", _pose(t_s, r["pos_ned_m"], r.get("att_rad")))]

    def _sim_grab(self, t_s: float, r: dict[str, Any]) -> list[Message]:
        verdict = "caught" if r.get("caught") else ("slipped" if r.get("slipped") else "missed")
        text = f"grab {verdict}: gripper {r.get('error_m', math.nan):.3f} m from the object (simulator's truth)"
        return [("/log", fm.Log(timestamp=stamp(t_s), level=fm.LogLevel.Info, message=text, name="sim"))]


def _log_line(r: dict[str, Any]) -> fm.Log:
    kind = r["kind"]
    if kind == "state":
        text = f"{r.get('from') or ''} → {r['to']}: {r.get('reason', '')}".lstrip()
    else:
        text = " ".join(f"{k}={v}" for k, v in r.items() if k not in ("t_s", "kind"))
    bad = (kind == "command" and r.get("result") not in OK_RESULTS) or (kind == "gcs" and not r.get("accepted"))
    level = fm.LogLevel.Warning if bad else fm.LogLevel.Info
    return fm.Log(timestamp=stamp(r["t_s"]), level=level, message=text, name=kind)


class RunChannels:
    """The run's channels on one SDK context (an MCAP writer's or a live server's), each made with its first message."""

    def __init__(self, context: foxglove.Context, run_dir: Path | None = None) -> None:
        self.context = context
        self.mapper = RecordMapper(run_dir)
        self.channels: dict[str, Any] = {}
        self.logged = 0  # messages
        self.skipped = 0  # records of a shape the mapping does not know (a field missing, a camera file gone)

    def log(self, record: dict[str, Any]) -> None:
        try:
            log_time, messages = time_ns(record["t_s"]), self.mapper.messages(record)
        except (KeyError, IndexError, TypeError, ValueError, OSError):
            self.skipped += 1
            return
        for topic, message in messages:
            self._channel(topic).log(message, log_time=log_time)
            self.logged += 1

    def close(self) -> None:
        for channel in self.channels.values():
            channel.close()
        self.channels.clear()

    def _channel(self, topic: str) -> Any:
        channel = self.channels.get(topic)
        if channel is None:
            if topic in JSON_SCHEMAS:
                channel = foxglove.Channel(topic, schema=JSON_SCHEMAS[topic], context=self.context)
            else:
                channel = TYPED_CHANNELS[topic](topic, context=self.context)
            self.channels[topic] = channel
        return channel


def run_records(run_dir: Path) -> list[dict[str, Any]]:
    """The run's records in time order: the event log's, and the simulator's (kinds ``sim.*``, on the app's clock)."""
    records = [r for r in read_jsonl(run_dir / "events.jsonl") if isinstance(r.get("t_s"), (int, float))]
    sim_log = run_dir / "sim_state.jsonl"
    if sim_log.exists():
        records += _sim_records(sim_log)
    return sorted(records, key=lambda r: r["t_s"])  # stable: records of one instant keep their order


def _sim_records(path: Path) -> Iterator[dict[str, Any]]:
    offset_s = 0.0
    for r in read_jsonl(path):
        event = r.get("event")
        if event == "start":
            offset_s = float(r.get("boot_monotonic_s", 0.0))
        elif event in ("object", "truth", "grab") and isinstance(r.get("t_s"), (int, float)):
            yield r | {"kind": f"sim.{event}", "t_s": r["t_s"] + offset_s}


def write_mcap(run_dir: Path) -> Path:
    """Write ``run_dir/run.mcap`` from the run's records (replacing one there; a failed write leaves none)."""
    out = run_dir / MCAP_NAME
    partial = run_dir / f"{MCAP_NAME}.partial"
    out.unlink(missing_ok=True)
    records = run_records(run_dir)
    context = foxglove.Context()
    channels = RunChannels(context, run_dir)
    try:
        with foxglove.open_mcap(partial, allow_overwrite=True, context=context) as writer:
            for r in records:
                channels.log(r)
            channels.close()
            metadata = {"run_dir": run_dir.name, "records": len(records), "skipped": channels.skipped}
            writer.write_metadata("seapick", {k: str(v) for k, v in metadata.items()})
        partial.replace(out)
    finally:
        partial.unlink(missing_ok=True)
    return out
