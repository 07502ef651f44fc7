"""What an evaluation of the pickup leaves behind: the summary per configuration (table and JSON), ``report.png``
(touchdown-error CDF per configuration, success by sea state) and ``index.html`` (every run, linked to its report
when ``--run-reports`` wrote one)."""

from __future__ import annotations

import html
from collections import Counter
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from sim.pickup_world import CONTACT_M

GOALS_M = (0.08, 0.20)  # the long-term and current touchdown p95 goals


def _pct(values: Sequence[float], q: float) -> float | None:
    return round(float(np.percentile(values, q)), 4) if values else None


TOUCHDOWN_BY = ("estimator", "profile", "object_kind")  # scenario fields the touchdown error is split by


def _touchdown_by(rs: Sequence[dict[str, Any]]) -> dict[str, dict[str, dict[str, Any]]]:
    """Per value of each of ``TOUCHDOWN_BY``: the touchdown error p50/p95 and how many touched down, and the
    off-target touchdowns of all its runs (a run that never picked up may have met the water off the object). At a
    calm sea the autopilot's estimator error, not the sea, makes seapick's tail (README, *Evaluating*)."""
    out: dict[str, dict[str, dict[str, Any]]] = {}
    for field in TOUCHDOWN_BY:
        groups: dict[str, list[dict[str, Any]]] = {}
        for r in rs:
            if field in r["scenario"]:
                groups.setdefault(str(r["scenario"][field]), []).append(r)
        out[field] = {}
        for k, runs in sorted(groups.items()):
            v = [r["touchdown_error_m"] for r in runs if r["touchdown_error_m"] is not None]
            if not v and not any(r["off_target_touchdowns"] for r in runs):
                continue  # (as before: a value none of whose runs touched down is not listed)
            out[field][k] = {
                "touchdowns": len(v),
                "p50_m": _pct(v, 50),
                "p95_m": _pct(v, 95),
                "off_target_touchdowns": sum(r["off_target_touchdowns"] for r in runs),
            }
    return out


def summarise(results: Sequence[dict[str, Any]], configs: Sequence[str]) -> dict[str, Any]:
    """Per configuration: runs, success rate (picked up by the mission's word *and* the simulator's truth; a
    mission that says picked_up with an empty gripper is a ``false_pickups``), touchdown error p50/p95/max
    (runs that touched down), how high over the water the gripper closed on the catches (p50/p95, and how many
    closed it before the vehicle had touched the water: ``caught_above_water``), time to
    pickup, off-target touchdowns, envelope and safety violations, aborts by reason, the touchdown error by
    estimator preset, autopilot and object (``touchdown_by``), speed-up over real time
    (mission time over the runs' own wall time); and ``ratio_p95`` = the first configuration's p95 over the
    second's, or null with ``ratio_p95_why`` saying why (a configuration that never touched down has no p95)."""
    out: dict[str, Any] = {"configs": {}}
    for name in configs:
        rs = [r for r in results if r["config"] == name]
        # success from the truth: the mission said picked_up *and* a grab caught the object (lines written before
        # ``caught`` existed count on the mission's word)
        picked = [r for r in rs if r["outcome"] == "picked_up" and r.get("caught", True)]
        false_pickups = [r for r in rs if r["outcome"] == "picked_up" and not r.get("caught", True)]
        errors = [r["touchdown_error_m"] for r in rs if r["touchdown_error_m"] is not None]
        times = [r["time_to_pickup_s"] for r in picked if r["time_to_pickup_s"] is not None]
        grab_heights = [r["grab_height_m"] for r in picked if r.get("grab_height_m") is not None]
        wall_s = sum(r["wall_s"] for r in rs)
        by_sea: dict[str, list[int]] = {}
        for r in rs:
            by_sea.setdefault(str(r["scenario"]["sea_state"]), []).append(r in picked)
        out["configs"][name] = {
            "runs": len(rs),
            "picked_up": len(picked),
            "false_pickups": len(false_pickups),  # the mission said picked_up, the gripper was empty
            "success_rate": round(len(picked) / len(rs), 4) if rs else None,
            "touchdown_p50_m": _pct(errors, 50),
            "touchdown_p95_m": _pct(errors, 95),
            "touchdown_max_m": round(max(errors), 4) if errors else None,
            "touchdowns": len(errors),
            "grab_height_p50_m": _pct(grab_heights, 50),
            "grab_height_p95_m": _pct(grab_heights, 95),
            "caught_above_water": sum(1 for h in grab_heights if h > CONTACT_M),
            "time_to_pickup_p50_s": _pct(times, 50),
            "time_to_pickup_p95_s": _pct(times, 95),
            "off_target_touchdowns": sum(r["off_target_touchdowns"] for r in rs),
            "envelope_violations": sum(r["envelope_violations"] for r in rs),
            "safety_violations": sum(len(r["safety_violations"]) for r in rs),
            "outcomes": dict(Counter(r["outcome"] for r in rs).most_common()),
            "aborts_by_reason": dict(Counter(r["abort_reason"] for r in rs if r["abort_reason"]).most_common()),
            "success_by_sea_state": {k: round(sum(v) / len(v), 4) for k, v in sorted(by_sea.items())},
            "touchdown_by": _touchdown_by(rs),
            "speedup_vs_real_time": round(sum(r["mission_s"] for r in rs) / wall_s, 1) if wall_s > 0 else None,
        }
    out["ratio_p95"] = None
    if len(configs) >= 2:
        a, b = (out["configs"][c]["touchdown_p95_m"] for c in configs[:2])
        out["ratio_p95"] = round(a / b, 3) if a is not None and b else None
        if out["ratio_p95"] is None:  # say why there is nothing to divide, rather than leave a bare null
            out["ratio_p95_why"] = (
                "; ".join(
                    f"{c} touched down in none of its {out['configs'][c]['runs']} runs"
                    for c in configs[:2]
                    if out["configs"][c]["touchdowns"] == 0
                )
                or f"{configs[1]}'s p95 is 0"
            )
    return out


def _m(v: float | None) -> str:
    return "—" if v is None else f"{v:.3f}"


def _off(group: dict[str, Any]) -> str:
    """What follows a group's touchdowns in the table: its off-target touchdowns when it had any (nothing for
    summaries written before they were counted)."""
    n = group.get("off_target_touchdowns", 0)
    return f", {n} off-target" if n else ""


def table(summary: dict[str, Any]) -> str:
    cs = summary["configs"]
    rows = [
        f"{'config':10} {'runs':>5} {'success':>8} {'td p50 m':>9} {'td p95 m':>9} {'td max m':>9} "
        f"{'pickup p50 s':>12} {'off-target':>10} {'envelope':>8} {'safety':>6} {'speed-up':>8}"
    ]
    for name, c in cs.items():
        rate = "—" if c["success_rate"] is None else f"{100 * c['success_rate']:.1f}%"
        tp = "—" if c["time_to_pickup_p50_s"] is None else f"{c['time_to_pickup_p50_s']:.1f}"
        speed = "—" if c["speedup_vs_real_time"] is None else f"{c['speedup_vs_real_time']:.0f}x"
        rows.append(
            f"{name:10} {c['runs']:>5} {rate:>8} {_m(c['touchdown_p50_m']):>9} {_m(c['touchdown_p95_m']):>9} "
            f"{_m(c['touchdown_max_m']):>9} {tp:>12} {c['off_target_touchdowns']:>10} {c['envelope_violations']:>8} "
            f"{c['safety_violations']:>6} {speed:>8}"
        )
    names = list(cs)
    if summary.get("ratio_p95") is not None:
        rows.append(f"ratio p95 {names[0]}/{names[1]}: {summary['ratio_p95']:.2f}")
    elif summary.get("ratio_p95_why"):
        rows.append(f"ratio p95 {names[0]}/{names[1]}: — ({summary['ratio_p95_why']})")
    for name, c in cs.items():
        by_sea = ", ".join(f"SS{k} {100 * v:.0f}%" for k, v in c["success_by_sea_state"].items())
        rows.append(
            f"{name}: outcomes {c['outcomes']}; success by sea state: {by_sea}; "
            f"false pickups (said picked_up, gripper empty): {c['false_pickups']}"
        )
        if c["grab_height_p50_m"] is not None:
            rows.append(
                f"  gripper closed over the water (catches): p50 {_m(c['grab_height_p50_m'])} m, "
                f"p95 {_m(c['grab_height_p95_m'])} m; before touching it (> {CONTACT_M:g} m): "
                f"{c['caught_above_water']} of {c['picked_up']}"
            )
        for field, groups in c.get("touchdown_by", {}).items():
            if groups:
                parts = (
                    f"{k} {_m(g['p50_m'])}/{_m(g['p95_m'])} ({g['touchdowns']}{_off(g)})" for k, g in groups.items()
                )
                rows.append(f"  touchdown p50/p95 m by {field}: " + ", ".join(parts))
        for reason, n in c["aborts_by_reason"].items():
            rows.append(f"  {n:4d}  {reason}")
    return "\n".join(rows)


def write_report_png(results: Sequence[dict[str, Any]], summary: dict[str, Any], path: Path) -> Path:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (cdf, bars) = plt.subplots(1, 2, figsize=(13, 5))
    names = list(summary["configs"])
    for k, name in enumerate(names):
        errs = np.sort(
            [r["touchdown_error_m"] for r in results if r["config"] == name and r["touchdown_error_m"] is not None]
        )
        if errs.size:
            runs = summary["configs"][name]["runs"]
            cdf.step(
                errs,
                np.arange(1, errs.size + 1) / runs,
                where="post",
                color=f"C{k}",
                label=f"{name} ({errs.size}/{runs} touched down)",
            )
    for g in GOALS_M:
        cdf.axvline(g, color="0.6", ls="--", lw=0.8)
    cdf.set_xlabel("touchdown error (gripper to object, horizontal), m")
    cdf.set_ylabel("fraction of runs")
    cdf.set_title("touchdown error CDF (dashed: 0.08 m, 0.20 m)")
    cdf.grid(alpha=0.3)
    cdf.legend()
    seas = sorted({s for n in names for s in summary["configs"][n]["success_by_sea_state"]}, key=int)
    width = 0.8 / max(len(names), 1)
    for k, name in enumerate(names):
        rates = [summary["configs"][name]["success_by_sea_state"].get(s, 0.0) for s in seas]
        bars.bar(np.arange(len(seas)) + k * width, rates, width, label=name, color=f"C{k}")
    bars.set_xticks(np.arange(len(seas)) + width * (len(names) - 1) / 2, [f"SS {s}" for s in seas])
    bars.set_ylim(0, 1.05)
    bars.set_ylabel("picked up")
    bars.set_title("success by sea state")
    bars.legend()
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return path


def write_index_html(results: Sequence[dict[str, Any]], summary_text: str, out_dir: Path) -> Path:
    """A page with the summary and one row per run, linking its report when the run directory has one."""
    rows = []
    for r in results:
        sc = r["scenario"]
        run_dir = out_dir / "runs" / r["config"] / f"{r['run']:04d}"
        links = " ".join(
            f'<a href="{html.escape(str((run_dir / f).relative_to(out_dir)))}">{f}</a>'
            for f in ("report.png", "events.jsonl", "run.mcap")
            if (run_dir / f).exists()
        )
        cells = [r["config"], r["run"], r["seed"], sc["sea_state"], sc["object_kind"], sc["clutter"], sc["profile"],
                 sc["estimator"], r["outcome"], _m(r["touchdown_error_m"]), r["time_to_pickup_s"] or "—",
                 r["abort_reason"] or "", links]  # fmt: skip
        rows.append("<tr>" + "".join(f"<td>{c if c is links else html.escape(str(c))}</td>" for c in cells) + "</tr>")
    head = ["config", "run", "seed", "sea state", "object", "clutter", "autopilot", "estimator", "outcome",
            "touchdown m", "to pickup s", "gave up", "files"]  # fmt: skip
    page = (
        "<!doctype html><meta charset='utf-8'><title>seapick evaluation</title>"
        "<style>td,th{padding:2px 6px;font:12px monospace}tr:nth-child(even){background:#f3f3f3}</style>"
        f"<h1>seapick pickup evaluation</h1><pre>{html.escape(summary_text)}</pre>"
        "<p><img src='report.png'></p><p><a href='results.jsonl'>results.jsonl</a></p>"
        "<table><tr>" + "".join(f"<th>{h}</th>" for h in head) + "</tr>" + "".join(rows) + "</table>"
    )
    path = out_dir / "index.html"
    path.write_text(page)
    return path
