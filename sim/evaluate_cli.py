"""``python -m sim.evaluate [--runs N] [--jobs J] [--seed S] [--sea-state N] [--compare A,B] [--json] [--out DIR]
[--dask ADDRESS] [--run-reports] [--mission FILE]``: the pickup over many randomised scenarios, in virtual time.

``--runs`` scenarios are drawn from ``--seed`` (``sim.pickup_scenarios``) and each is flown with every
configuration (``--compare thesis,seapick``; default ``seapick``) — the same scenarios for each — on ``--jobs``
local processes or on the Dask cluster at ``--dask``, with the mission ``--mission`` (default the built-in
``pickup``: a copy of it with other parameters, e.g. for a windy site, flies the same scenarios). A progress bar
goes to stderr; ``DIR`` (default ``runs/eval-<seed>``) gets ``results.jsonl`` (a line per run,
``sim.evaluate_pickup``), ``summary.json``, ``report.png`` and ``index.html`` (while it runs,
``results.partial.jsonl`` gets each result as it comes in, so a run that dies keeps what it flew). On stdout: the
summary table, or with ``--json`` one JSON object, the table then going to stderr (per configuration runs,
success_rate, touchdown_p50_m, touchdown_p95_m, off_target_touchdowns, envelope_violations,
speedup_vs_real_time, …; ``ratio_p95`` = the first configuration's p95 over the second's, null with
``ratio_p95_why`` when one of them never touched down).
"""

from __future__ import annotations

import argparse
import json
import os
import re
import sys
import time
from pathlib import Path
from typing import Any

from app.cli import OneLineParser, name_list, number, run_cli
from sim.evaluate_jobs import Job, Progress, run_jobs
from sim.evaluate_pickup import RunInputs
from sim.evaluate_report import summarise, table, write_index_html, write_report_png
from sim.native import active as native_active
from sim.pickup_scenarios import CONFIGS, sample_scenarios

PARTIAL_RESULTS = "results.partial.jsonl"  # results as they come in, removed once results.jsonl is written
DASK_ADDRESS = re.compile(r"^(tcp|tls|inproc|ucx)://\S+$")


config_list = name_list(CONFIGS)


def dask_address(text: str) -> str:
    if not DASK_ADDRESS.match(text):
        raise argparse.ArgumentTypeError(f"{text!r} is not a scheduler address like tcp://host:8786")
    return text


def parse_args(argv: list[str] | None) -> Any:
    p = OneLineParser(prog="python -m sim.evaluate", description=__doc__.split("\n\n")[0])
    p.add_argument("--runs", type=number(1, 100_000, kind=int), default=20, help="scenarios (each flown per config)")
    p.add_argument("--jobs", type=number(1, 256, kind=int), default=os.cpu_count() or 1, help="local processes")
    p.add_argument("--seed", type=number(0, 2**31 - 1, kind=int), default=1, help="draws the scenarios")
    p.add_argument("--sea-state", type=number(0, 5, kind=int), default=None, help="fixed WMO code (default: 0–4 drawn)")
    p.add_argument("--compare", type=config_list, default=("seapick",), help="configurations, e.g. thesis,seapick")
    p.add_argument("--json", action="store_true", help="one JSON object on stdout instead of the table")
    p.add_argument("--out", type=Path, default=None, help="output directory (default runs/eval-<seed>)")
    p.add_argument(
        "--dask", type=dask_address, default=None, metavar="ADDRESS", help="a Dask scheduler, tcp://host:port"
    )
    p.add_argument("--run-reports", action="store_true", help="every run's event log and report.png under DIR/runs/")
    p.add_argument("--no-progress", action="store_true", help="no progress bar on stderr")
    p.add_argument(
        "--mission", default="pickup", metavar="FILE", help="the mission every run flies (default: the built-in pickup)"
    )
    return p.parse_args(argv)


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    inputs = RunInputs.load(args.mission)  # once: editing the settings or the mission while it runs changes no run
    out: Path = args.out if args.out is not None else Path("runs") / f"eval-{args.seed}"
    out.mkdir(parents=True, exist_ok=True)  # after the mission is read: a bad one leaves nothing behind
    scenarios = sample_scenarios(args.seed, args.runs, args.sea_state)
    jobs: list[Job] = []
    for config in args.compare:
        for i, sc in enumerate(scenarios):
            run_dir = None
            if args.run_reports:
                d = out / "runs" / config / f"{i:04d}"
                d.mkdir(parents=True, exist_ok=True)
                run_dir = str(d.resolve())
            jobs.append((sc, config, i, run_dir, inputs))
    wall0 = time.perf_counter()
    progress = None if args.no_progress else Progress(len(jobs))
    # each result is on disk as soon as it is in (completion order): an evaluation that dies keeps what it flew
    partial = out / PARTIAL_RESULTS
    with partial.open("w") as pf:

        def on_result(r: dict[str, Any]) -> None:
            pf.write(json.dumps(r) + "\n")
            pf.flush()
            if progress is not None:
                progress(r)

        results = run_jobs(jobs, args.jobs, args.dask, on_result)
    wall_s = time.perf_counter() - wall0
    with (out / "results.jsonl").open("w") as f:  # in job order
        for r in results:
            f.write(json.dumps(r) + "\n")
    partial.unlink()
    summary = summarise(results, args.compare)
    summary |= {
        "seed": args.seed,
        "runs": args.runs,
        "sea_state": args.sea_state,
        "wall_s": round(wall_s, 1),
        "jobs": args.jobs,
        "dask": args.dask,
        "mission": args.mission,
        "native": native_active(),  # this process's simulator modules compiled (``sim.native``): its workers' too
        "out": str(out),
    }
    (out / "summary.json").write_text(json.dumps(summary, indent=1) + "\n")
    text = table(summary)
    write_report_png(results, summary, out / "report.png")
    write_index_html(results, text, out)
    if args.json:
        print(json.dumps(summary))
        print(text, file=sys.stderr)  # the table for the reader, next to the progress bar
    else:
        print(text)
        files = ", ".join(str(out / f) for f in ("results.jsonl", "report.png", "index.html"))
        print(f"{len(results)} runs in {wall_s:.1f} s; {files}")
    return 0


if __name__ == "__main__":
    sys.exit(run_cli(main, "python -m sim.evaluate"))
