"""``python -m app.bench triangulation [--json]``: horizontal error of sea-plane triangulation, flat sea.

Each case: a vehicle 2–25 m above a flat sea moves at ``--speed-mps`` (random direction, ±0.5 m/s²,
±0.3 m/s vertically) and rotates — roll and pitch oscillate with amplitudes 10–20° at a peak rate of
``--rate-dps``, yaw turns at ±``--rate-dps`` — while its telemetry (position/velocity and attitude, separate
streams, ``--telemetry-hz`` with their own phases) fills a ``StateHistory``. A camera frame is captured at
``t_c``; a known sea-plane point inside the field of view is projected (pure numpy + the camera model, with
distortion) and gets ``--pixel-noise-px`` Gaussian noise. The frame is processed ``--max-latency-ms`` × U(0, 1)
later, at ``t_p``. The fix is triangulated twice:

- **interp**: vehicle state interpolated at ``t_c`` (position linear, attitude slerp), radar height at
  ``t_c``; when no telemetry newer than ``t_c`` has arrived by ``t_p`` the frame waits for the next sample
  (≤ one telemetry period), as the app does;
- **no_interp**: the newest telemetry sample at ``t_p`` and the radar height at that sample's time
  (what the thesis did).

Errors are horizontal, metres and relative to the camera's true height at capture. The camera and
radar lever arms are the settings' (camera) and ``RADAR_ARM_FRD_M``; the triangulator applies both.
``cov95_interp`` is the fraction of interp errors inside their own 95 % covariance ellipse (χ²₂ ≤ 5.99).
"""

from __future__ import annotations

import argparse
import json
import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from app.cli import OneLineParser, number
from app.estimators.rotations import euler_zyx_to_matrix
from app.estimators.state_history import StateHistory
from app.estimators.triangulation import SeaPlaneTriangulator
from app.messages import AttitudeEuler, PositionVelocityNed
from app.settings import CameraSettings

RADAR_ARM_FRD_M = (0.05, -0.08, 0.12)  # a plausible radar mount, m
MAX_OFF_VERTICAL_RAD = math.radians(75.0)
CHI2_2DOF_95 = 5.991
GOAL_P95_REL = 0.01  # done-when: p95 ≤ 1 % of height with interpolation
HEIGHT_BINS_M = ((0.0, 5.0), (5.0, 10.0), (10.0, 30.0))  # camera height; the lever arm puts some just under 2 m
LATENCY_BINS_MS = ((0, 50), (50, 100), (100, 150), (150, 200), (200, 250))


@dataclass(frozen=True, eq=False)
class Motion:
    """The vehicle's true motion around the capture time t = 0."""

    pos0_ned_m: np.ndarray
    vel_ned_mps: np.ndarray
    acc_ned_mps2: np.ndarray
    amp_rad: np.ndarray  # roll, pitch amplitudes
    omega_radps: np.ndarray  # roll, pitch angular frequencies
    phase_rad: np.ndarray
    yaw0_rad: float
    yaw_rate_radps: float

    def pos(self, t: float) -> np.ndarray:
        return self.pos0_ned_m + self.vel_ned_mps * t + 0.5 * self.acc_ned_mps2 * t * t

    def vel(self, t: float) -> np.ndarray:
        return self.vel_ned_mps + self.acc_ned_mps2 * t

    def euler(self, t: float) -> tuple[float, float, float]:
        rp = self.amp_rad * np.sin(self.omega_radps * t + self.phase_rad)
        return float(rp[0]), float(rp[1]), self.yaw0_rad + self.yaw_rate_radps * t

    def R_ned_frd(self, t: float) -> np.ndarray:
        return euler_zyx_to_matrix(*self.euler(t))


def _motion(rng: np.random.Generator, height_m: float, speed_mps: float, rate_radps: float) -> Motion:
    heading = rng.uniform(0.0, 2 * math.pi)
    vel = np.array([speed_mps * math.cos(heading), speed_mps * math.sin(heading), rng.uniform(-0.3, 0.3)])
    acc = np.append(rng.normal(0.0, 0.5, 2), 0.0)
    amp = rng.uniform(math.radians(10.0), math.radians(20.0), 2)
    return Motion(
        pos0_ned_m=np.array([0.0, 0.0, -height_m]),
        vel_ned_mps=vel,
        acc_ned_mps2=acc,
        amp_rad=amp,
        omega_radps=rate_radps / amp,  # peak roll/pitch rate = amplitude × ω
        phase_rad=rng.uniform(0.0, 2 * math.pi, 2),
        yaw0_rad=rng.uniform(-math.pi, math.pi),
        yaw_rate_radps=float(rng.choice([-1.0, 1.0])) * rate_radps,
    )


def _radar_height_m(m: Motion, t: float) -> float:
    """What a perfect radar reads at ``t``: its height above the flat sea (down = 0)."""
    return float(-(m.pos(t) + m.R_ned_frd(t) @ np.asarray(RADAR_ARM_FRD_M))[2])


def _fill_history(m: Motion, phases_s: tuple[float, float], rate_hz: float, until_s: float) -> StateHistory:
    """Telemetry from t = −1 s to ``until_s``: position/velocity and attitude streams with their own phases."""
    h = StateHistory()
    period = 1.0 / rate_hz
    for t in np.arange(-1.0 + phases_s[0], until_s + 1e-12, period):
        p, v = m.pos(t), m.vel(t)
        h.add_pos_vel(PositionVelocityNed(float(t), (p[0], p[1], p[2]), (v[0], v[1], v[2])))
    for t in np.arange(-1.0 + phases_s[1], until_s + 1e-12, period):
        h.add_attitude(AttitudeEuler(float(t), *m.euler(float(t))))
    return h


def _target(m: Motion, tri: SeaPlaneTriangulator, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray] | None:
    """A sea point in the view at t = 0 and its (noise-free, distorted) pixel."""
    cam = tri.camera
    R_ned_frd = m.R_ned_frd(0.0)
    R_ned_cam = R_ned_frd @ tri.R_frd_cam
    cam_ned = m.pos(0.0) + R_ned_frd @ np.asarray(tri.cam_arm_frd_m)
    xy = rng.uniform(-1.0, 1.0, 2) * np.array([cam.cx_px / cam.fx_px, cam.cy_px / cam.fy_px])
    d = R_ned_cam @ np.array([xy[0], xy[1], 1.0])
    if d[2] <= 0.0 or math.atan2(math.hypot(d[0], d[1]), d[2]) > MAX_OFF_VERTICAL_RAD:
        return None
    point_ned = cam_ned + (-cam_ned[2] / d[2]) * d  # the sea is at down = 0
    pixel = cam.project(R_ned_cam.T @ (point_ned - cam_ned))[0]
    if not cam.in_image(pixel, margin_px=1.0)[0]:
        return None
    return point_ned, pixel


def run(args: argparse.Namespace) -> dict[str, Any]:
    rng = np.random.default_rng(args.seed)
    tri = SeaPlaneTriangulator.from_settings(
        CameraSettings(pixel_noise_std_px=args.pixel_noise_px),
        radar_arm_frd_m=RADAR_ARM_FRD_M,
        max_off_vertical_rad=math.radians(85.0),
    )
    rate = math.radians(args.rate_dps)
    period_s = 1.0 / args.telemetry_hz
    rows: list[tuple[float, float, float, float, float]] = []
    waited = 0
    while len(rows) < args.cases:
        m = _motion(rng, rng.uniform(2.0, 25.0), args.speed_mps, rate)
        target = _target(m, tri, rng)
        if target is None:
            continue
        truth_ned, pixel = target
        pixel = pixel + rng.normal(0.0, args.pixel_noise_px, 2)
        latency_s = rng.uniform(0.0, args.max_latency_ms / 1000.0)
        phases = (float(rng.uniform(0.0, period_s)), float(rng.uniform(0.0, period_s)))
        h_noise_m = rng.normal(0.0, args.height_noise_m)
        # What has arrived by the processing time t_p = latency …
        at_tp = _fill_history(m, phases, args.telemetry_hz, until_s=latency_s)
        span = at_tp.span_s()
        if span is None or span[1] < 0.0:  # … does not bracket t_c yet: wait for the next sample
            waited += 1
            at_tc = _fill_history(m, phases, args.telemetry_hz, until_s=latency_s + period_s)
        else:
            at_tc = at_tp
        interp = tri.fix_pixel(0.0, pixel, at_tc.at(0.0), _radar_height_m(m, 0.0) + h_noise_m, args.height_noise_m)
        latest = at_tp.latest()
        stale = tri.fix_pixel(0.0, pixel, latest, _radar_height_m(m, latest.t_s) + h_noise_m, args.height_noise_m)
        if interp is None or stale is None:
            continue
        cam_height_m = float(-(m.pos(0.0) + m.R_ned_frd(0.0) @ np.asarray(tri.cam_arm_frd_m))[2])
        e_i = np.asarray(interp.observation.pos_ned_m[:2]) - truth_ned[:2]
        e_s = np.asarray(stale.observation.pos_ned_m[:2]) - truth_ned[:2]
        nis = float(e_i @ np.linalg.solve(np.asarray(interp.observation.cov_ne_m2), e_i))
        rows.append((cam_height_m, latency_s, float(np.hypot(*e_i)), float(np.hypot(*e_s)), nis))
    out = _summarise(np.array(rows), args)
    out["interp_waited_for_telemetry_fraction"] = waited / len(rows)
    return out


def _pcts(err_m: np.ndarray, h_m: np.ndarray) -> dict[str, float]:
    rel = err_m / h_m
    return {
        "p50_m": float(np.percentile(err_m, 50)),
        "p95_m": float(np.percentile(err_m, 95)),
        "p50_rel_height": float(np.percentile(rel, 50)),
        "p95_rel_height": float(np.percentile(rel, 95)),
    }


def _summarise(a: np.ndarray, args: argparse.Namespace) -> dict[str, Any]:
    h, lat, e_i, e_s, nis = a.T
    interp, stale = _pcts(e_i, h), _pcts(e_s, h)
    by_height = {}
    for lo, hi in HEIGHT_BINS_M:
        sel = (h >= lo) & (h < hi)
        by_height[f"{max(lo, 2.0):g}-{min(hi, 25.0):g}m"] = {"n": int(sel.sum()), "interp": _pcts(e_i[sel], h[sel]),
                                        "no_interp": _pcts(e_s[sel], h[sel])}  # fmt: skip
    by_latency = {}
    for lo_ms, hi_ms in LATENCY_BINS_MS:
        sel = (lat * 1000 >= lo_ms) & (lat * 1000 < hi_ms)
        by_latency[f"{lo_ms}-{hi_ms}ms"] = {"n": int(sel.sum()), "interp": _pcts(e_i[sel], h[sel]),
                                           "no_interp": _pcts(e_s[sel], h[sel])}  # fmt: skip
    return {
        "bench": "triangulation",
        "interp": interp,
        "no_interp": stale,
        "cases": len(a),
        "seed": args.seed,
        "conditions": {
            "height_m": [2.0, 25.0],
            "attitude_max_deg": 20.0,
            "pixel_noise_px": args.pixel_noise_px,
            "height_noise_m": args.height_noise_m,
            "latency_ms": [0.0, args.max_latency_ms],
            "speed_mps": args.speed_mps,
            "attitude_rate_dps": args.rate_dps,
            "telemetry_hz": args.telemetry_hz,
            "sea": "flat",
        },
        "p50_m_interp": interp["p50_m"],
        "p95_m_interp": interp["p95_m"],
        "p50_rel_height_interp": interp["p50_rel_height"],
        "p95_rel_height_interp": interp["p95_rel_height"],
        "p50_m_no_interp": stale["p50_m"],
        "p95_m_no_interp": stale["p95_m"],
        "p50_rel_height_no_interp": stale["p50_rel_height"],
        "p95_rel_height_no_interp": stale["p95_rel_height"],
        "ratio_p95_no_interp_over_interp": stale["p95_rel_height"] / max(interp["p95_rel_height"], 1e-12),
        "cov95_interp": float(np.mean(nis <= CHI2_2DOF_95)),
        "goal_p95_rel_height": GOAL_P95_REL,
        "goal_met": bool(interp["p95_rel_height"] <= GOAL_P95_REL),
        "by_height": by_height,
        "by_latency": by_latency,
    }


def _format(r: dict[str, Any]) -> str:
    c = r["conditions"]
    lines = [
        f"triangulation bench: {r['cases']} cases, flat sea, heights {c['height_m'][0]:g}–{c['height_m'][1]:g} m, "
        f"attitude ±{c['attitude_max_deg']:g}°, pixel noise {c['pixel_noise_px']:g} px, height noise "
        f"{c['height_noise_m']:g} m, latency 0–{c['latency_ms'][1]:g} ms, {c['speed_mps']:g} m/s, "
        f"{c['attitude_rate_dps']:g}°/s, telemetry {c['telemetry_hz']:g} Hz",
        f"{'horizontal error / height':<27}{'interp p50':>11}{'p95':>10}{'no-interp p50':>16}{'p95':>10}",
    ]

    def row(name: str, n: int, i: dict[str, float], s: dict[str, float]) -> str:
        return (
            f"{name:<16}n={n:<5}{100 * i['p50_rel_height']:>13.3f} %{100 * i['p95_rel_height']:>8.3f} %"
            f"{100 * s['p50_rel_height']:>14.3f} %{100 * s['p95_rel_height']:>8.3f} %"
        )

    lines.append(row("all", r["cases"], r["interp"], r["no_interp"]))
    for group in ("by_height", "by_latency"):
        for name, b in r[group].items():
            lines.append(row(name, b["n"], b["interp"], b["no_interp"]))
    lines += [
        f"p95 metres: interp {r['p95_m_interp']:.3f} m, no-interp {r['p95_m_no_interp']:.3f} m; "
        f"no-interp/interp p95 ratio {r['ratio_p95_no_interp_over_interp']:.1f}×",
        f"interp errors inside their own 95 % covariance ellipse: {100 * r['cov95_interp']:.1f} %; "
        f"frames that waited ≤ 1 telemetry period for interpolation: "
        f"{100 * r['interp_waited_for_telemetry_fraction']:.1f} %",
        f"goal p95 ≤ {100 * r['goal_p95_rel_height']:g} % of height with interpolation: "
        + ("MET" if r["goal_met"] else "NOT MET"),
    ]
    return "\n".join(lines)


def main(argv: list[str]) -> int:
    ap = OneLineParser(prog="python -m app.bench triangulation", description=__doc__.split("\n")[0])
    ap.add_argument("--json", action="store_true", help="print one JSON object")
    ap.add_argument("--cases", type=number(1, 10_000_000, "", int), default=3000, help="Monte Carlo cases")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--pixel-noise-px", type=number(0.0, 20.0, "px"), default=0.5, help="pixel noise (std), px")
    ap.add_argument("--height-noise-m", type=number(0.0, 5.0, "m"), default=0.0, help="radar height noise (std), m")
    ap.add_argument(
        "--max-latency-ms", type=number(0.0, 5000.0, "ms"), default=250.0, help="largest capture-to-fix latency"
    )
    ap.add_argument("--speed-mps", type=number(0.0, 30.0, "m/s"), default=2.0, help="vehicle speed, m/s")
    ap.add_argument(
        "--rate-dps", type=number(0.0, 720.0, "deg/s"), default=30.0, help="peak roll/pitch rate and yaw rate, deg/s"
    )
    ap.add_argument("--telemetry-hz", type=number(1.0, 1000.0, "Hz"), default=50.0, help="telemetry rate, Hz")
    args = ap.parse_args(argv)
    result = run(args)
    print(json.dumps(result) if args.json else _format(result))
    return 0
