"""Read a run's ``run.mcap`` back with the ``mcap`` reader (protobuf through ``mcap-protobuf-support``, JSON here) and
check it against the run's own records: the helpers the Foxglove tests and the evaluation's test share."""

from __future__ import annotations

import json
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from mcap.decoder import DecoderFactory
from mcap.reader import make_reader
from mcap.records import Schema
from mcap_protobuf.decoder import DecoderFactory as ProtobufDecoderFactory

from app.foxglove_log import run_records, time_ns

# every pickup run has these (a run without an estimate, a radar height or a fix would be no pickup at all)
PICKUP_TOPICS = {
    "/tf": "foxglove.FrameTransforms",
    "/vehicle/pose": "foxglove.PoseInFrame",
    "/vehicle/truth": "foxglove.PoseInFrame",
    "/object/truth": "foxglove.PoseInFrame",
    "/object/estimate": "foxglove.PoseInFrame",
    "/object/covariance": "foxglove.SceneUpdate",
    "/detections": "foxglove.SceneUpdate",
    "/setpoint": "seapick.Setpoint",
    "/radar/height": "seapick.RadarHeight",
    "/mission/state": "seapick.MissionState",
    "/log": "foxglove.Log",
}


class JsonDecoderFactory(DecoderFactory):
    def decoder_for(self, message_encoding: str, schema: Schema | None) -> Callable[[bytes], Any] | None:
        return json.loads if message_encoding == "json" else None


@dataclass
class Recording:
    schemas: dict[str, str] = field(default_factory=dict)  # topic → schema name
    counts: dict[str, int] = field(default_factory=dict)  # topic → messages, from the summary's statistics
    messages: dict[str, list[tuple[int, Any]]] = field(default_factory=dict)  # topic → (log time ns, decoded)
    metadata: dict[str, dict[str, str]] = field(default_factory=dict)


def read_mcap(path: Path) -> Recording:
    """Every channel and every message of ``path``, decoded, channel by channel, in the order they were written."""
    rec = Recording()
    with path.open("rb") as f:
        reader = make_reader(f, decoder_factories=[ProtobufDecoderFactory(), JsonDecoderFactory()])
        summary = reader.get_summary()
        assert summary is not None and summary.statistics is not None
        for channel_id, channel in summary.channels.items():
            rec.schemas[channel.topic] = summary.schemas[channel.schema_id].name
            rec.counts[channel.topic] = summary.statistics.channel_message_counts.get(channel_id, 0)
        for topic in rec.schemas:
            rec.messages[topic] = [
                (m.log_time, decoded)
                for _, _, m, decoded in reader.iter_decoded_messages(topics=[topic], log_time_order=False)
            ]
        rec.metadata = {m.name: dict(m.metadata) for m in reader.iter_metadata()}
    return rec


def check_run_mcap(run_dir: Path, topics: dict[str, str] = PICKUP_TOPICS) -> Recording:
    """``run_dir/run.mcap`` has every topic of ``topics`` with its schema and messages, each channel's log times
    non-decreasing and inside the records' t_s range; a ``pickup`` record half-way through the run is there as the
    vehicle's pose and the object's estimate, to the digit."""
    rec = read_mcap(run_dir / "run.mcap")
    records = run_records(run_dir)
    t0_ns, t1_ns = time_ns(records[0]["t_s"]), time_ns(records[-1]["t_s"])
    for topic, schema in topics.items():
        assert rec.schemas.get(topic) == schema, (topic, rec.schemas.get(topic))
        times = [t for t, _ in rec.messages[topic]]
        assert len(times) == rec.counts[topic] > 0, topic
        assert times == sorted(times), topic
        assert t0_ns <= times[0] and times[-1] <= t1_ns, topic
    traced = [r for r in records if r["kind"] == "pickup"]
    candidates = [r for r in traced if r["estimate_ne_m"] is not None] or traced  # a run that saw the object: its
    r = candidates[len(candidates) // 2]  # estimate too
    t_ns = time_ns(r["t_s"])
    vehicle = dict(rec.messages["/vehicle/pose"])[t_ns]
    assert vehicle.frame_id == "ned"
    assert (vehicle.timestamp.seconds, vehicle.timestamp.nanos) == divmod(t_ns, 1_000_000_000)
    assert position(vehicle) == [*r["vehicle_ne_m"], r["vehicle_down_m"]]
    if r["estimate_ne_m"] is not None:
        estimate = dict(rec.messages["/object/estimate"])[t_ns]
        assert estimate.frame_id == "ned" and position(estimate) == [*r["estimate_ne_m"], r["estimate_down_m"]]
    assert rec.metadata["seapick"]["skipped"] == "0"
    return rec


def position(pose_in_frame: Any) -> list[float]:
    p = pose_in_frame.pose.position
    return [p.x, p.y, p.z]
