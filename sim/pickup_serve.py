"""The pickup's world inside the simulated autopilot's process: the sea, the floating object, the camera and
the radar the app reads as if they were real.

``PickupServer`` attaches to a ``SimAutopilot`` (its flight stack is the vehicle) and serves:

- the camera: rendered frames over a local socket (``sim.camera_serve``), the vehicle's true pose carried to
  the capture instant, the object at its true pose on the waves (hidden once caught: it hangs in the gripper);
- the radar: the X4M03 emulator on a pty (``sim.radar_live``) with echoes from the vehicle's true height and
  attitude over the same sea, at a stable link path (like udev's /dev/serial/by-id names);
- the judge: when the gripper closes, whether the object was caught (``sim.pickup_world.judge_grab``: within
  the capture radius, a gentle touchdown), logged as a ``grab`` record in the state log, with ``object``
  records (its true position) every 0.1 s — the run's truth for ``touchdown_error_m`` and the report.

One time base: simulation time ``t_s = time.monotonic() − boot`` (``SimAutopilot.boot_monotonic_s``), which
the state log, the sea, the radar and the camera's stamps (CLOCK_MONOTONIC) all agree on. The sea's frame is
the autopilot's local NED frame: the vehicle boots on the mean sea surface (down = 0), as in the in-process
world (``sim.pickup_world``).
"""

from __future__ import annotations

import math
import threading
from dataclasses import dataclass, field

from app.settings import CameraSettings, DetectorSettings
from sim.autopilot_endpoint import SimAutopilot
from sim.camera_render_poses import Pose, camera_pose, object_pose
from sim.camera_serve import CameraFrameServer
from sim.pickup_world import PickupOutcome, PickupScenario, judge_grab, water_down_m, water_vel_ne_mps
from sim.radar import RadarEmulator
from sim.radar_live import live_sea_emulator, truth_at_from_snapshots
from sim.sea import FloatingObject, SeaConfig, SeaWorld
from sim.stack_types import Truth

OBJECT_LOG_PERIOD_S = 0.1


WATER_PERIOD_S = 1.0 / 30.0  # how often the water under the vehicle is looked up


@dataclass(frozen=True)
class ServeConfig:
    scenario: PickupScenario = field(default_factory=PickupScenario)
    camera_address: str | None = None  # e.g. unix:/run/seapick/camera.sock; None: no camera
    radar_link: str | None = None  # the pty's stable path; None: no radar
    camera_fps_hz: float = 15.0
    wind_mps: float = 0.0  # the object's windage


class PickupServer:
    def __init__(
        self, sim: SimAutopilot, config: ServeConfig, camera: CameraSettings, detector: DetectorSettings
    ) -> None:
        self.sim = sim
        self.config = config
        sc = config.scenario
        self.sea = SeaWorld(SeaConfig(sea_state=sc.sea_state, current_mps=sc.current_mps), seed=sc.seed)
        self.object = FloatingObject(self.sea, start_ne_m=sc.object_start_ne_m)
        self.outcome = PickupOutcome()
        self._lock = threading.Lock()
        self._gripper_closed = False
        self._next_object_log_s = 0.0
        self._next_water_s = 0.0
        self._truth_at = truth_at_from_snapshots(sim.truth)
        self._camera_settings = camera
        self.camera: CameraFrameServer | None = None
        if config.camera_address is not None:
            self.camera = CameraFrameServer(
                config.camera_address,
                camera,
                detector.model_copy(update={"marker_size_m": sc.marker_size_m}),
                self._scene,
                fps_hz=config.camera_fps_hz,
                seed=sc.seed,
            )
        self.radar: RadarEmulator | None = None
        if config.radar_link is not None:
            self.radar = live_sea_emulator(
                self.sea, self._truth_at, config.radar_link, sc.seed, epoch_monotonic_s=sim.boot_monotonic_s
            )
        sim.add_observer(self._observe)

    def start(self) -> None:
        if self.camera is not None:
            self.camera.start()
        if self.radar is not None:
            self.radar.start()
        sc = self.config.scenario
        self.sim.log(
            "world",
            sea_state=sc.sea_state,
            current_mps=sc.current_mps,
            object_start_ne_m=list(sc.object_start_ne_m),
            capture_radius_m=sc.capture_radius_m,
            camera=self.camera.address if self.camera is not None else None,
            radar=self.config.radar_link,
        )

    def close(self) -> None:
        if self.camera is not None:
            self.camera.close()
        if self.radar is not None:
            self.radar.stop()

    # -- the camera's scene (render thread) -------------------------------------------------------------------

    def _scene(self, t_monotonic_s: float) -> tuple[Pose, Pose | None]:
        t_s = t_monotonic_s - self.sim.boot_monotonic_s
        pose = self._truth_at(t_s)
        if pose is None:  # the vehicle does not exist yet: a camera on the ground looking at nothing
            pos, roll, pitch, yaw = (0.0, 0.0, 0.0), 0.0, 0.0, 0.0
        else:
            pos, roll, pitch, yaw = pose
        cam = camera_pose(pos, roll, pitch, yaw, self._camera_settings)  # type: ignore[arg-type]
        with self._lock:
            caught = self.outcome.caught
        return cam, None if caught else object_pose(self.object, t_s)

    # -- the judge (endpoint thread, after every physics tick) --------------------------------------------------

    def _observe(self, truth: Truth) -> None:
        t_s = truth.t_s
        if truth.gripper_closed and not self._gripper_closed:
            with self._lock:
                grab = judge_grab(self.outcome, self.config.scenario, self.object, t_s, truth)
            self.sim.log("grab", t_s, **{k: v for k, v in grab.items() if k != "t_s"})
        self._gripper_closed = truth.gripper_closed
        if t_s >= self._next_water_s:  # the vehicle meets the water on the waves (``water_down_m``)
            self._next_water_s = t_s + WATER_PERIOD_S
            dyn = self.sim.stack.dyn
            dyn.ground_down_m = water_down_m(self.sea, t_s, truth.pos_ned_m)
            dyn.ground_vel_ne_mps = water_vel_ne_mps(self.sea, t_s, truth.pos_ned_m)
        if t_s >= self._next_object_log_s:
            self._next_object_log_s = t_s + OBJECT_LOG_PERIOD_S
            o = self.object.state(t_s)
            self.sim.log("object", t_s, pos_ned_m=o.pos_ned_m, caught=self.outcome.caught)


def object_start_ne_m(distance_m: float, bearing_deg: float) -> tuple[float, float]:
    b = math.radians(bearing_deg)
    return distance_m * math.cos(b), distance_m * math.sin(b)
