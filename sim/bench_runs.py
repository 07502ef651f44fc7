"""``python -m sim.bench_runs [--runs N] [--seed S] [--sea-state N] [--configs A,B] [--json] [--save FILE]
[--compare FILE]``: what one in-process evaluation run costs (``sim.evaluate_pickup.run_pickup``).

The first ``--runs`` scenarios of ``--seed`` (``sim.pickup_scenarios``, sea state 3 unless told) are flown with each
configuration, one after the other in this process, as a ``python -m sim.evaluate`` job flies them. Per
configuration it prints the wall time per run (median, p95), the CPU time per run (median; this process and its
threads — less disturbed than the wall time by other work on the machine) and the speed-up against real time
(mission time over wall time, of the median run and of all runs together). The project's goal is about 120× (a
2-minute pickup costs about a second of CPU).

A speed-up must not change what a run does: ``--save FILE`` writes the results (without ``wall_s``) as JSON,
``--compare FILE`` checks that this build gives exactly the same ones (exit status 1 if not, naming the runs and
fields that differ).
"""

from __future__ import annotations

import os

# As ``python -m sim.evaluate`` runs them: one OpenBLAS thread (see there), set before anything imports numpy.
if __name__ == "__main__":
    os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

# isort: split
import json
import statistics
import sys
import time
from pathlib import Path
from typing import Any

from app.cli import OneLineParser, number, run_cli
from sim.evaluate_cli import config_list
from sim.evaluate_pickup import run_pickup
from sim.pickup_scenarios import sample_scenarios


def parse_args(argv: list[str] | None) -> Any:
    p = OneLineParser(prog="python -m sim.bench_runs", description=__doc__.split("\n\n")[0])
    p.add_argument("--runs", type=number(1, 10_000, kind=int), default=6, help="scenarios (each flown per config)")
    p.add_argument("--seed", type=number(0, 2**31 - 1, kind=int), default=1, help="draws the scenarios")
    p.add_argument("--sea-state", type=number(0, 5, kind=int), default=3, help="WMO code of every scenario")
    p.add_argument("--configs", type=config_list, default=("seapick", "thesis"), help="e.g. seapick,thesis")
    p.add_argument("--json", action="store_true", help="one JSON object on stdout instead of the table")
    p.add_argument("--save", type=Path, default=None, help="write the results (without wall_s) to this file")
    p.add_argument("--compare", type=Path, default=None, help="check the results against this --save file")
    return p.parse_args(argv)


def _p95(xs: list[float]) -> float:
    ordered = sorted(xs)
    return ordered[min(len(ordered) - 1, round(0.95 * (len(ordered) - 1)))]


def cost_summary(mission_s: list[float], wall_s: list[float], cpu_s: list[float]) -> dict[str, float]:
    """Per-run cost figures of one configuration (seconds; speed-ups as mission time over wall time)."""
    ratios = [m / w for m, w in zip(mission_s, wall_s, strict=True) if w > 0.0]
    return {
        "runs": len(wall_s),
        "mission_s_total": round(sum(mission_s), 2),
        "wall_s_median": round(statistics.median(wall_s), 3),
        "wall_s_p95": round(_p95(wall_s), 3),
        "cpu_s_median": round(statistics.median(cpu_s), 3),
        "speedup_median": round(statistics.median(ratios), 1) if ratios else 0.0,
        "speedup_total": round(sum(mission_s) / sum(wall_s), 1) if sum(wall_s) > 0.0 else 0.0,
    }


def differences(reference: list[dict[str, Any]], results: list[dict[str, Any]]) -> list[str]:
    """Every run whose result differs from the reference's, with the fields that differ."""
    out = [f"{len(results)} results against {len(reference)}"] if len(reference) != len(results) else []
    for ref, new in zip(reference, results, strict=False):
        fields = sorted(k for k in ref.keys() | new.keys() if ref.get(k) != new.get(k))
        if fields:
            out.append(f"{new.get('config')} run {new.get('run')}: {', '.join(fields)}")
    return out


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    scenarios = sample_scenarios(args.seed, args.runs, args.sea_state)
    results: list[dict[str, Any]] = []
    summary: dict[str, Any] = {}
    for config in args.configs:
        mission_s, wall_s, cpu_s = [], [], []
        for i, sc in enumerate(scenarios):
            cpu0 = time.process_time()
            r = run_pickup(sc, config, i)
            cpu_s.append(time.process_time() - cpu0)
            wall_s.append(r.pop("wall_s"))
            mission_s.append(r["mission_s"])
            results.append(r)
            if not args.json:
                print(
                    f"{config} run {i}: {r['outcome']}, {r['mission_s']:.0f} s of mission in {wall_s[-1]:.2f} s "
                    f"(cpu {cpu_s[-1]:.2f} s, {r['mission_s'] / max(wall_s[-1], 1e-9):.0f}x)",
                    file=sys.stderr,
                )
        summary[config] = cost_summary(mission_s, wall_s, cpu_s)
    # through JSON, as a saved file reads back (tuples become lists)
    results = json.loads(json.dumps(results))
    if args.save is not None:
        args.save.write_text(json.dumps(results, indent=1, sort_keys=True) + "\n")
    diffs = differences(json.loads(args.compare.read_text()), results) if args.compare is not None else []
    if args.json:
        print(json.dumps(summary | ({"identical": not diffs} if args.compare is not None else {})))
    else:
        for config, s in summary.items():
            print(
                f"{config:8s} {s['runs']} runs, {s['mission_s_total']:.0f} s of mission: wall per run median "
                f"{s['wall_s_median']:.2f} s, p95 {s['wall_s_p95']:.2f} s; cpu median {s['cpu_s_median']:.2f} s; "
                f"speed-up vs real time {s['speedup_median']:.1f}x (median run), {s['speedup_total']:.1f}x (all)"
            )
        if args.compare is not None:
            print("results identical to " + str(args.compare) if not diffs else "results DIFFER: " + "; ".join(diffs))
    return 1 if diffs else 0


if __name__ == "__main__":
    sys.exit(run_cli(main, "python -m sim.bench_runs"))
