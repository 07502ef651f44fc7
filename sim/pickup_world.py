"""The pickup's world for in-process runs: the sea, the floating object, and the sensors the app reads.

The in-process vehicle (``sim.inproc``) flies; this adds what the camera and the radar would report, at
their own rates and with their latency, computed from the truth:

- camera (geometric mode, ``sim.camera_geometry``): every ``frame_period_s`` the marker's corners projected
  from the vehicle's true pose, handed to the mission ``latency_s`` later (``frame_latency_s``) with the *capture*
  time (``stamp_at_arrival``: the time it arrives, as a pipeline without latency compensation would). With nested
  markers (``DetectorSettings.nested_marker_ids``, sized as ``app.sensors.detect_marker`` expects) the largest
  one wholly in the image and at least ``MIN_EDGE_PX`` across is what the detector reports, with its size;
- radar: the radar's true height above the sea surface under the vehicle (waves included), plus noise.

It also judges the pickup from the truth: where the vehicle was relative to the object when the gripper closed
(``touchdown_error_m``) and whether the object was caught: within ``capture_radius_m``, with a gentle touchdown
(vertical speed ≤ ``gentle_mps``) and the vehicle on the water under it (no higher than ``GRIP_REACH_M``;
``height_m`` in the grab's record says how high it was, the evaluation reports it); ``fail_first_grabs`` makes
the first grabs miss regardless. A caught object hangs in the gripper: the camera no longer sees it on the sea.
"""

from __future__ import annotations

import asyncio
import dataclasses
import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from app.clock import sleep_on
from app.estimators.rotations import euler_zyx_to_matrix
from app.missions.pickup import RadarCalibrator
from app.missions.pickup_feeds import CameraObservation, HeightSample, PickupFeeds
from app.sensors.detect_marker import SEARCH_FULL_MIN_PX, marker_sizes_m
from app.settings import Settings
from sim.camera_geometry import GeometricCamera, mean_edge_px
from sim.inproc import InProcessVehicle
from sim.sea import FloatingObject, SeaConfig, SeaWorld

MIN_EDGE_PX = SEARCH_FULL_MIN_PX  # a smaller marker is not decoded
MIN_BUOY_PX = 8.0  # a buoy smaller than this across is not found (the buoy detector's smallest radius, with margin)
BUOY_NOISE_PX = 1.0  # the buoy detector's centre: a Hough circle refined by the disc's moments (or its rim)
# The buoy detector finds a buoy cut by the image's edge while this share of its outline is in the image (its rim
# then gives the centre, within 1.5 px): on rendered frames it found one with 53 % in (cut by one edge) and 59 %
# (at a corner), and lost it at 51 % and 50 %.
BUOY_RIM_IN_IMAGE = 0.6


def rim_in_image(centre_px: tuple[float, float], radius_px: float, width_px: int, height_px: int) -> float:
    """The share of a circle's outline inside a ``width_px`` × ``height_px`` image (72 points)."""
    a = np.linspace(0.0, 2.0 * math.pi, 72, endpoint=False)
    u, v = centre_px[0] + radius_px * np.cos(a), centre_px[1] + radius_px * np.sin(a)
    return float(np.mean((u >= 0.0) & (u <= width_px - 1) & (v >= 0.0) & (v <= height_px - 1)))


@dataclass
class PickupScenario:
    seed: int = 1
    sea_state: int = 2
    current_mps: float = 0.3
    current_to_deg: float = 60.0  # where the current flows to, degrees from north (SeaConfig's default)
    object_start_ne_m: tuple[float, float] = (40.0, 20.0)
    marker_size_m: float = 0.30
    object_kind: str = "marker"  # or "buoy": a sphere of the detector's buoy_diameter_m
    frame_period_s: float = 1.0 / 15.0
    latency_s: float = 0.06
    # no latency compensation (the thesis): a detection reaches the mission stamped with the time it *arrives*,
    # so it is paired with the vehicle's state then, not at the frame's capture
    stamp_at_arrival: bool = False
    pixel_noise_px: float = 0.5
    radar_noise_m: float = 0.02
    radar_range_m: float = 5.0  # the radar's last range (settings.radar.frame_area_end_m)
    radar_min_range_m: float = 0.45  # … and its first (the frame area's start, the pulse's length)
    radar_fps_hz: float = 10.0
    # a sea echo that reaches this far past the last range (a range ambiguity, a strong swell): the background
    # capture fails until the vehicle is higher still
    radar_echo_beyond_range_m: float = 0.0
    capture_radius_m: float = 0.25
    gentle_mps: float = 1.0
    fail_first_grabs: int = 0  # these many grabs miss whatever the touchdown (a gripper that slipped)


@dataclass
class PickupOutcome:
    touchdown_error_m: float | None = None
    touchdown_speed_mps: float | None = None
    caught: bool = False
    grabs: list[dict[str, Any]] = field(default_factory=list)
    # every time the vehicle came down onto the water (away from the deck): when, and how far from the object
    contacts: list[dict[str, Any]] = field(default_factory=list)


class PickupWorld:
    def __init__(self, vehicle: InProcessVehicle, scenario: PickupScenario, settings: Settings) -> None:
        """``settings``: the vehicle as the app describes it (camera, detector's marker set, radar lever arm) —
        here they are also the truth."""
        self.vehicle = vehicle
        self.scenario = sc = scenario
        self.sea = SeaWorld(
            SeaConfig(sea_state=sc.sea_state, current_mps=sc.current_mps, current_to_deg=sc.current_to_deg),
            seed=sc.seed,
        )
        self.object = FloatingObject(self.sea, start_ne_m=sc.object_start_ne_m)
        self.camera = GeometricCamera(
            settings.camera, marker_size_m=sc.marker_size_m, pixel_noise_std_px=sc.pixel_noise_px, seed=sc.seed
        )
        self.radar_arm_frd_m = np.asarray(settings.radar.lever_arm_frd_m, dtype=np.float64)
        self.rng = np.random.default_rng(sc.seed + 1000)
        self.marker_sizes_m = marker_sizes_m(settings.detector.model_copy(update={"marker_size_m": sc.marker_size_m}))
        self.buoy_diameter_m = settings.detector.buoy_diameter_m
        self.outcome = PickupOutcome()
        self._gripper_closed = False
        self._on_water = False
        # per camera frame, from the truth: (t_s, height above the sea, down speed, the sea surface's down speed
        # under the vehicle) — for checking descents from the vehicle's side
        self.samples: list[tuple[float, float, float, float]] = []
        self.calibrations = 0
        self.calibrated_at_m: float | None = None
        self.camera_blind = False  # set from outside: the marker is not detected (glare, spray, occlusion)
        # called at every camera frame with (t_s, the vehicle's truth, the object's state): watching only — a task
        # of its own would wake the loop at other instants and change the flight it watches
        self.frame_observers: list[Callable[[float, Any, Any], None]] = []

    async def calibrate_radar(self, n_frames: int) -> None:
        """The radar's background capture (``n_frames`` at ``radar_fps_hz``): it fails while the sea is in range."""
        loop = asyncio.get_running_loop()
        sc = self.scenario
        for _ in range(n_frames):
            await asyncio.sleep(1.0 / sc.radar_fps_hz)
            p = self.vehicle.truth().pos_ned_m
            height_m = -float(self.sea.surface_elevation_m(loop.time(), p[0], p[1])) - p[2]
            if height_m <= sc.radar_range_m + sc.radar_echo_beyond_range_m:
                raise RuntimeError(f"an echo at {height_m:.1f} m: the sea is in range")
        self.calibrations += 1
        self.calibrated_at_m = height_m

    async def sensors(self, feeds: PickupFeeds) -> None:
        """The camera and the radar, producing into the mission's queues until cancelled."""
        feeds.set_radar_calibrator(RadarCalibrator(self.scenario.radar_range_m, self.calibrate_radar))
        loop = asyncio.get_running_loop()
        pending: list[tuple[float, CameraObservation]] = []  # (when it reaches the mission, the observation)
        next_s = loop.time()
        sc = self.scenario
        while True:
            next_s += sc.frame_period_s
            delay_s = next_s - loop.time()
            await (sleep_on(loop, delay_s) if delay_s > 0.0 else asyncio.sleep(0))
            t_s = loop.time()
            truth = self.vehicle.truth()
            o = self.object.state(t_s)
            for observe in self.frame_observers:
                observe(t_s, truth, o)
            p = truth.pos_ned_m
            sea_down = -float(self.sea.surface_elevation_m(t_s, p[0], p[1]))
            sea_vel = self.sea.surface_velocity_ned_mps(t_s, p[0], p[1])
            dyn = self.vehicle.stack.dyn  # at the frame rate
            dyn.ground_down_m, dyn.ground_vel_ne_mps = (
                water_down_m(self.sea, t_s, p, sea_down),
                water_vel_ne_mps(self.sea, t_s, p, sea_vel),
            )
            # the radar measures from its antenna, off the body origin by the lever arm
            r_ned_body = euler_zyx_to_matrix(truth.roll_rad, truth.pitch_rad, truth.yaw_rad)
            ant = np.asarray(p) + r_ned_body @ self.radar_arm_frd_m
            sea_under_antenna_down = -float(self.sea.surface_elevation_m(t_s, ant[0], ant[1]))
            antenna_m = sea_under_antenna_down - ant[2]
            if sc.radar_min_range_m <= antenna_m <= sc.radar_range_m:  # outside its ranges the radar sees no sea
                # what the radar task hands on: the body origin's height over the sea under the antenna (its
                # estimator takes the lever arm out)
                body_m = sea_under_antenna_down - p[2]
                feeds.heights.put(HeightSample(t_s, body_m + float(self.rng.normal(0.0, sc.radar_noise_m))))
            sea_wd = float(sea_vel[2])
            self.samples.append((t_s, sea_down - p[2], truth.vel_ned_mps[2], sea_wd))
            self._note_contact(t_s, sea_down - p[2], p, o.pos_ned_m)
            # after the contact: a gripper that closed since the last frame, with the vehicle now on the water, met
            # the water too (judged first, a catch in the frame of the touchdown hid that touchdown)
            self._judge_grab(t_s, truth)
            # a caught object hangs in the gripper, out of the camera's sea
            blind = self.outcome.caught or self.camera_blind
            if blind:
                seen = CameraObservation(t_s)
            elif sc.object_kind == "buoy":
                seen = self._buoy_seen(t_s, truth, o.pos_ned_m)
            else:
                seen = self._largest_seen(t_s, truth, o.pos_ned_m)
            # frames are handed over in order: one never overtakes the one before it
            due_s = max(t_s + self.frame_latency_s(), pending[-1][0] if pending else -math.inf)
            pending.append((due_s, seen))
            while pending and pending[0][0] <= t_s:
                seen = pending.pop(0)[1]
                feeds.frames.put(dataclasses.replace(seen, t_s=t_s) if sc.stamp_at_arrival else seen)

    def frame_latency_s(self) -> float:
        """Capture → detection handed to the mission for the frame being captured, s (``latency_s``)."""
        return self.scenario.latency_s

    def _largest_seen(self, t_s: float, truth: Any, centre_ned_m: Any) -> CameraObservation:
        """The largest marker of the set wholly in the image and big enough to decode (its corners, its edge)."""
        p = truth.pos_ned_m
        for size_m in self.marker_sizes_m:
            f = self.camera.frame(
                t_s, p, truth.roll_rad, truth.pitch_rad, truth.yaw_rad, centre_ned_m, marker_size_m=size_m
            )
            c = f.corners_true_px
            edge_px = mean_edge_px(c)
            if f.visible and edge_px >= MIN_EDGE_PX:
                return CameraObservation(t_s, tuple((float(u), float(v)) for u, v in f.corners_px), size_m)
        return CameraObservation(t_s)

    def _buoy_seen(self, t_s: float, truth: Any, centre_ned_m: Any) -> CameraObservation:
        """The buoy's centre (with the detector's noise) and diameter, when enough of it is in the image (wholly, or
        ``BUOY_RIM_IN_IMAGE`` of its outline: low over it, it spills over the edge) and it is big enough. Its outline
        is taken as a level disc's of its diameter: within a few per cent of a sphere's in the image's middle."""
        p = truth.pos_ned_m
        f = self.camera.frame(
            t_s, p, truth.roll_rad, truth.pitch_rad, truth.yaw_rad, centre_ned_m, marker_size_m=self.buoy_diameter_m
        )
        c = f.corners_true_px
        diameter_px = mean_edge_px(c)
        if not diameter_px >= MIN_BUOY_PX or not (f.visible or self._rim_seen(f.centre_true_px, diameter_px)):
            return CameraObservation(t_s)
        u, v = f.centre_true_px + self.rng.normal(0.0, BUOY_NOISE_PX, 2)
        return CameraObservation(t_s, center_px=(float(u), float(v)), diameter_px=diameter_px)

    def _rim_seen(self, centre_px: Any, diameter_px: float) -> bool:
        m = self.camera.model
        c = (float(centre_px[0]), float(centre_px[1]))
        return rim_in_image(c, diameter_px / 2.0, m.width_px, m.height_px) >= BUOY_RIM_IN_IMAGE

    def _note_contact(self, t_s: float, height_m: float, pos_ned_m: Any, object_ned_m: Any) -> None:
        """A touchdown on the water (the vehicle within ``CONTACT_M`` of the sea under it, away from the deck; it
        counts again only after the vehicle was ``CONTACT_CLEAR_M`` up): recorded with its distance to the object,
        until a grab caught it."""
        if self.outcome.caught or math.hypot(float(pos_ned_m[0]), float(pos_ned_m[1])) <= DECK_RADIUS_M:
            return  # the object hangs in the gripper (its truth floats on, untouched); or the vehicle is on deck
        if not self._on_water and height_m <= CONTACT_M:
            err = math.hypot(pos_ned_m[0] - object_ned_m[0], pos_ned_m[1] - object_ned_m[1])
            self.outcome.contacts.append({"t_s": t_s, "error_m": err})
            self._on_water = True
        elif self._on_water and height_m > CONTACT_CLEAR_M:
            self._on_water = False

    def _judge_grab(self, t_s: float, truth: Any) -> None:
        if truth.gripper_closed and not self._gripper_closed:
            judge_grab(self.outcome, self.scenario, self.object, t_s, truth)
        self._gripper_closed = truth.gripper_closed


DECK_RADIUS_M = 5.0  # around home the vehicle stands on the deck (down 0); beyond, on the sea
CONTACT_M = 0.05  # the vehicle this close to the water under it has touched down on it …
CONTACT_CLEAR_M = 0.3  # … and a next touchdown needs it this high first
# a grab catches with the vehicle (its lowest point) no higher than this over the water under it: on it, give or
# take the waves' motion in a tick (0.5 before 2026-12-01: most catches at sea state 3 closed the gripper before
# the vehicle touched the water; README, *Evaluating*: where the gripper closed)
GRIP_REACH_M = 0.1


def water_down_m(sea: SeaWorld, t_s: float, pos_ned_m: Any, sea_down_m: float | None = None) -> float:
    """Where the vehicle meets the water under it (down): the sea surface, crests and troughs included — a vehicle
    come down onto the sea sits on the wave, not on a flat plane through its mean. Within ``DECK_RADIUS_M`` of
    home: the deck, at home level. ``sea_down_m``: the sea surface's down there, when the caller has it already."""
    if math.hypot(float(pos_ned_m[0]), float(pos_ned_m[1])) <= DECK_RADIUS_M:
        return 0.0
    if sea_down_m is not None:
        return sea_down_m
    return -float(sea.surface_elevation_m(t_s, pos_ned_m[0], pos_ned_m[1]))


def water_vel_ne_mps(sea: SeaWorld, t_s: float, pos_ned_m: Any, surface_vel_ned_mps: Any = None) -> tuple[float, float]:
    """How the water under the vehicle moves it when it sits on it (``water_down_m``): the surface's orbital
    velocity and the current, horizontal, m/s — as they move the object. Within ``DECK_RADIUS_M`` of home: the
    deck stands still. (Before 2026-12-01 the sea held a vehicle on it still, as the ground does, while the object
    orbited on: on the water 0.07-0.2 s before the gripper closed, it ended up to 0.11 m farther off it.)
    ``surface_vel_ned_mps``: the surface's velocity there, when the caller has it already."""
    n, e = float(pos_ned_m[0]), float(pos_ned_m[1])
    if math.hypot(n, e) <= DECK_RADIUS_M:
        return 0.0, 0.0
    orbital = sea.surface_velocity_ned_mps(t_s, n, e) if surface_vel_ned_mps is None else surface_vel_ned_mps
    _, (cn, ce), _ = sea.current_one(t_s)
    return float(orbital[0]) + cn, float(orbital[1]) + ce


def judge_grab(
    outcome: PickupOutcome, sc: PickupScenario, obj: FloatingObject, t_s: float, truth: Any
) -> dict[str, Any]:
    """The gripper just closed at ``t_s``: was the object caught? Recorded in ``outcome``; the record returned."""
    o = obj.state(t_s)
    err = math.hypot(truth.pos_ned_m[0] - o.pos_ned_m[0], truth.pos_ned_m[1] - o.pos_ned_m[1])
    height = -float(obj.sea.surface_elevation_m(t_s, *truth.pos_ned_m[:2])) - truth.pos_ned_m[2]
    speed = abs(float(truth.vel_ned_mps[2]))
    slipped = len(outcome.grabs) < sc.fail_first_grabs
    caught = err <= sc.capture_radius_m and speed <= sc.gentle_mps and height < GRIP_REACH_M and not slipped
    grab = {"t_s": t_s, "error_m": err, "height_m": height, "speed_mps": speed, "caught": caught, "slipped": slipped}
    outcome.grabs.append(grab)
    outcome.touchdown_error_m, outcome.touchdown_speed_mps = err, speed
    outcome.caught = outcome.caught or caught
    return grab
