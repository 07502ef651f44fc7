"""``python -m sim.evaluate filters [--sea-state N ...] [--horizons-s H,...] [--fix-height-m M] [--json]``: the target
filters against ground truth.

(Without ``filters``: the pickup's Monte Carlo evaluation, ``sim.evaluate_cli``.)

For each sea state, one seeded sea and object, one seeded stream of triangulated fixes (``sim.fixes``), fed
in delivery order to the thesis's constant-velocity filter and to the wave filter. After each fix (past a
warm-up) each filter predicts the object at +0, +0.5, +1 and +2 s (``--horizons-s``); the error is the
horizontal distance to the true object at that time. The constant-velocity filter's noise is tuned for it
first, on a separate seed and the same kind of fixes (the best p95 at 1 s over a grid), so the baseline is the
best it can be; the wave filter uses only the sea state's Hs and Tp.

By default the fixes come from 6 m up with the vehicle wandering 1.5 m around the object (``FixConfig``).
``--fix-height-m 1.2 --offset-std-m 0.1 --horizons-s 0,0.3,0.5,0.7`` asks what the last metre of DESCEND
needs: precise fixes right over the object, then the camera's blind half-second (the object spills out of
the picture below about 0.5 m, the radar sees no sea below 0.45 m; README, *Evaluating*).
"""

from __future__ import annotations

import os

# The evaluation's linear algebra is on tiny matrices (the filters' 12×12): a second OpenBLAS thread buys nothing
# and, with a process per core (``--jobs``), its spinning threads take the cores from the runs — milliseconds per
# call on a busy machine. OpenBLAS reads this when numpy loads it: set before anything imports numpy (the job
# processes inherit it). Only as the program: importing this module changes nobody's environment.
if __name__ == "__main__":
    os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

# isort: split
import itertools
import json
import sys
import time
from collections.abc import Callable, Sequence

import numpy as np

from app.cli import OneLineParser, number, number_list, run_cli
from app.estimators.cv_filter import ConstantVelocityFilter
from app.estimators.sea_state import SEA_STATES
from app.estimators.target_filter import LinearTargetFilter
from app.estimators.wave_filter import WaveFilter
from sim.fixes import FixConfig, FixStream, make_fixes
from sim.sea import FloatingObject, SeaConfig, SeaWorld

HORIZONS_S = (0.0, 0.5, 1.0, 2.0)
WARMUP_S = 20.0


def horizon_key(h_s: float) -> str:
    return f"{h_s:g}".replace(".", "p") + "s"


def prediction_errors(
    filt: LinearTargetFilter, fixes: FixStream, obj: FloatingObject, horizons_s: Sequence[float] = HORIZONS_S
) -> dict[float, np.ndarray]:
    """Horizontal prediction error (m) at each horizon, one sample per in-order fix after the warm-up."""
    times, hs, pred = [], [], []
    latest = -np.inf
    for obs in fixes.observations():
        filt.update(obs)
        if obs.t_s < latest:
            continue  # a late fix: fused, but predictions are evaluated from the newest fix only
        latest = obs.t_s
        if obs.t_s < WARMUP_S:
            continue
        for h in horizons_s:
            e = filt.estimate(obs.t_s + h)
            if e is not None:
                times.append(obs.t_s + h)
                hs.append(h)
                pred.append(e.pos_ned_m[:2])
    truth, _, _ = obj.states(np.asarray(times))
    err = np.hypot(*(np.asarray(pred) - truth[:, :2]).T)
    hs_a = np.asarray(hs)
    return {h: err[hs_a == h] for h in horizons_s}


# The constant-velocity filter's process noise is tuned on a grid of decades that grows past any edge the
# best point lands on, so the baseline is the best constant-velocity filter for the sea, not a straw man.
CV_GRID_START = {"q_pos_m2ps": (1e-4, 1e-3, 0.01, 0.1, 1.0), "q_vel_m2ps3": (1e-5, 1e-4, 1e-3, 0.01, 0.1, 1.0)}
CV_GRID_MAX_GROWTH = 4  # decades added per side at most


def tune_cv(sea_state: int, duration_s: float, seed: int, fix_config: FixConfig | None = None) -> dict[str, float]:
    sea = SeaWorld(SeaConfig(sea_state=sea_state), seed=seed)
    obj = FloatingObject(sea)
    fixes = make_fixes(sea, obj, duration_s, seed, fix_config if fix_config is not None else FixConfig())
    cache: dict[tuple[float, float], float] = {}

    def p95_1s(q_pos: float, q_vel: float) -> float:
        if (q_pos, q_vel) not in cache:
            errs = prediction_errors(ConstantVelocityFilter(q_pos, q_vel), fixes, obj, (1.0,))[1.0]
            cache[(q_pos, q_vel)] = float(np.percentile(errs, 95))
        return cache[(q_pos, q_vel)]

    grid = {k: list(v) for k, v in CV_GRID_START.items()}
    for _ in range(CV_GRID_MAX_GROWTH + 1):
        best = min(itertools.product(grid["q_pos_m2ps"], grid["q_vel_m2ps3"]), key=lambda q: p95_1s(*q))
        grown = False
        for value, axis in zip(best, grid.values(), strict=True):
            if value == axis[0]:
                axis.insert(0, axis[0] / 10.0)
                grown = True
            elif value == axis[-1]:
                axis.append(axis[-1] * 10.0)
                grown = True
        if not grown:
            break
    return {"q_pos_m2ps": best[0], "q_vel_m2ps3": best[1], "grid_points": len(cache)}


def evaluate_sea_state(
    sea_state: int,
    duration_s: float,
    seed: int,
    tune_duration_s: float = 180.0,
    horizons_s: Sequence[float] = HORIZONS_S,
    fix_config: FixConfig | None = None,
) -> dict[str, object]:
    ss = SEA_STATES[sea_state]
    cv_params = tune_cv(sea_state, tune_duration_s, seed + 1000, fix_config)
    sea = SeaWorld(SeaConfig(sea_state=sea_state), seed=seed)
    obj = FloatingObject(sea)
    fixes = make_fixes(sea, obj, duration_s, seed, fix_config if fix_config is not None else FixConfig())
    filters: dict[str, Callable[[], LinearTargetFilter]] = {
        "cv": lambda: ConstantVelocityFilter(cv_params["q_pos_m2ps"], cv_params["q_vel_m2ps3"]),
        "wave": lambda: WaveFilter(ss.hs_m, ss.tp_s),
    }
    out: dict[str, object] = {"hs_m": ss.hs_m, "tp_s": round(ss.tp_s, 3), "fixes": int(fixes.t_s.size),
                              "false_fixes": int(fixes.is_false.sum()), "late_fixes": int(fixes.is_late.sum()),
                              "cv_params": cv_params}  # fmt: skip
    p95: dict[tuple[str, float], float] = {}
    for name, make in filters.items():
        t0 = time.perf_counter()
        errs = prediction_errors(make(), fixes, obj, horizons_s)
        out[f"{name}_updates_per_s"] = round(fixes.t_s.size / (time.perf_counter() - t0))
        for h, e in errs.items():
            k = horizon_key(h)
            out[f"{name}_p50_{k}_m"] = round(float(np.percentile(e, 50)), 4)
            out[f"{name}_p95_{k}_m"] = p95[(name, h)] = round(float(np.percentile(e, 95)), 4)
    for h in horizons_s:
        w = p95[("wave", h)]
        out[f"ratio_{horizon_key(h)}"] = round(p95[("cv", h)] / w, 3) if w > 0 else None
    return out


def print_table(result: dict[str, dict[str, object]], horizons_s: Sequence[float] = HORIZONS_S) -> None:
    cols = [horizon_key(h) for h in horizons_s]
    print("p95 horizontal prediction error (m); ratio = CV / wave (higher is better for the wave filter)")
    head = " | ".join(f"{'CV ' + c:>9} {'wave ' + c:>9} {'ratio':>6}" for c in cols)
    print(f"{'SS':>2} {'Hs m':>5} {'Tp s':>5} | {head}")
    for code, r in result.items():
        cells = [f"{r[f'cv_p95_{c}_m']:>9.3f} {r[f'wave_p95_{c}_m']:>9.3f} {r[f'ratio_{c}']:>6.2f}" for c in cols]
        print(f"{code:>2} {r['hs_m']:>5.2f} {r['tp_s']:>5.2f} | " + " | ".join(cells))


def main(argv: list[str] | None = None) -> int:
    """``filters`` (the filter study), else the pickup's Monte Carlo evaluation (``sim.evaluate_cli``)."""
    args = sys.argv[1:] if argv is None else argv
    if args[:1] == ["filters"]:
        return filters_main(args)
    from sim.evaluate_cli import main as pickup_main

    return pickup_main(args)


def filters_main(argv: list[str] | None = None) -> int:
    p = OneLineParser(prog="python -m sim.evaluate", description=__doc__.split("\n\n")[0])
    sub = p.add_subparsers(dest="what", required=True)
    f = sub.add_parser("filters", help="constant-velocity vs wave filter prediction error by sea state")
    f.add_argument("--sea-state", type=int, action="append", choices=range(0, 6), help="repeatable (default 0–4)")
    f.add_argument("--duration-s", type=number(1.0, 86_400.0, "s"), default=600.0, help="length of each fix stream, s")
    f.add_argument("--seed", type=int, default=1)
    f.add_argument(
        "--tune-duration-s",
        type=number(1.0, 86_400.0, "s"),
        default=180.0,
        help="fix stream for tuning the CV baseline, s",
    )
    f.add_argument(
        "--horizons-s", type=number_list(0.0, 10.0, "s"), default=HORIZONS_S, help="e.g. 0,0.3,0.5 (default 0,0.5,1,2)"
    )
    f.add_argument(
        "--fix-height-m", type=number(0.5, 50.0, "m"), default=FixConfig.height_m, help="the camera over the sea, m"
    )
    f.add_argument(
        "--offset-std-m",
        type=number(0.0, 10.0, "m"),
        default=FixConfig.offset_std_m,
        help="how far the vehicle wanders around the object (σ), m",
    )
    f.add_argument("--json", action="store_true", help="one JSON object on stdout")
    args = p.parse_args(argv)
    codes = args.sea_state or [0, 1, 2, 3, 4]
    horizons = tuple(sorted(set(args.horizons_s)))
    fix_config = FixConfig(height_m=args.fix_height_m, offset_std_m=args.offset_std_m)
    result = {
        str(c): evaluate_sea_state(c, args.duration_s, args.seed, args.tune_duration_s, horizons, fix_config)
        for c in codes
    }
    if args.json:
        json.dump({"sea_states": result, "duration_s": args.duration_s, "seed": args.seed, "horizons_s": list(horizons),
                   "fix_height_m": args.fix_height_m, "offset_std_m": args.offset_std_m}, sys.stdout)  # fmt: skip
        print()
    else:
        print_table(result, horizons)
    return 0


if __name__ == "__main__":
    sys.exit(run_cli(main, "python -m sim.evaluate"))
