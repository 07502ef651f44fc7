"""The pickup's sensor tasks talk to its estimates through bounded latest-wins queues (``app.queues``).

Producers — the camera task (capture → detector, in a worker thread) and the radar task (driver → altitude
estimator), or the simulator's geometric sensors in process — put what they measured, stamped with the
time it was *measured*. Two consumer tasks on the event loop hand each item to ``PickupEstimates`` (the
only place its state changes, always on the loop's thread). A consumer that falls behind loses the oldest
items, never the newest, and every loss is counted for the run's summary.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from app.missions.pickup import PickupEstimates
from app.queues import LatestQueue

QUEUE_SIZE = 4


@dataclass(frozen=True, slots=True)
class MarkerObservation:
    """One processed camera frame: the marker's 4 raw corner pixels, or ``None`` when none was found."""

    t_s: float  # capture time (loop clock)
    corners_px: tuple[tuple[float, float], ...] | None
    size_m: float | None = None  # the physical edge of the marker seen (a nested one near touchdown); None: outer


@dataclass(frozen=True, slots=True)
class HeightSample:
    """The radar's height above the sea at ``t_s``; ``None`` when the radar is lost."""

    t_s: float
    height_m: float | None


class PickupFeeds:
    def __init__(self, maxsize: int = QUEUE_SIZE) -> None:
        self.frames: LatestQueue[MarkerObservation] = LatestQueue(maxsize)
        self.heights: LatestQueue[HeightSample] = LatestQueue(maxsize)

    async def consume_frames(self, model: PickupEstimates) -> None:
        while True:
            obs = await self.frames.get()
            if obs.corners_px is None:
                model.on_frame(obs.t_s)
            else:
                model.on_marker(obs.t_s, obs.corners_px, obs.size_m)

    async def consume_heights(self, model: PickupEstimates) -> None:
        while True:
            h = await self.heights.get()
            if h.height_m is None:
                model.on_radar_lost()
            else:
                model.on_height(h.t_s, h.height_m)

    def summary(self) -> dict[str, Any]:
        return {
            "queue_drops": {"camera": self.frames.dropped, "radar": self.heights.dropped},
            "queue_puts": {"camera": self.frames.put_count, "radar": self.heights.put_count},
        }
