"""The fault matrix: the circle mission in process and in virtual time, one fault per flying state, checked
from the vehicle's side.

    python -m sim.faults [--json] [--jobs N] [--only SUBSTRING] [--keep DIR]

Every case flies the real ``app.flight.fly_mission`` (one lap of the circle) against ``FaultyVehicle`` — the
in-process simulated autopilot with faults it can be told to show — on a looptime event loop, so a minute
of flight takes about a second. When the mission enters the case's state (TAKEOFF, TRACK or LAND) the fault
is injected; the run then goes on to its end and five more seconds of simulation. ``sim.safety_rules``
checks what the vehicle received. The table lists case × result; ``--json`` prints one object with
``cases``, ``passed`` and ``violations`` (each naming ``case`` and ``rule``). Exit status 1 if any rule is
broken.

Faults (``FAULTS``): a pilot switch to POSCTL (who lands 4 s later), a ground-station abort, an abort
while the state's command is slow to answer (2 s), the state's command refused, the state's command
accepted but never carried out (its mode never shows), an autopilot RTL or LAND failsafe the moment the
state's command was accepted (before the app could confirm its mode), position samples that stop, the
heartbeat that stops (other streams alive), the whole link lost, 200 ms of MAVLink delay each way from then
on, a 1 s event-loop stall, and 1 s of NaN position/attitude samples.
"""

from __future__ import annotations

import asyncio
import concurrent.futures
import json
import os
import sys
import tempfile
from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from pathlib import Path

import looptime

from app.cli import OneLineParser, run_cli
from app.clock import LoopClock
from app.eventlog import EventLog
from app.flight import fly_mission
from app.messages import FlightMode
from app.missions.runner import MissionRunner
from app.missions.table import MissionTable, load_mission
from app.settings import Settings
from sim.autopilot_modes import Profile
from sim.faulty_vehicle import NOOP_CYCLES, FaultyVehicle, stall_loop
from sim.safety_rules import Limits, RunFacts, Violation, check

SETTLE_S = 5.0  # simulated after the mission ends
CASE_LIMIT_S = 900.0  # virtual seconds; a case that runs longer is a violation, not a hang
FLYING_STATES = ("TAKEOFF", "TRACK", "LAND")
COMMAND_OF_STATE = {"TAKEOFF": "takeoff", "TRACK": "start_offboard", "LAND": "land"}
SLOW_COMMAND_OF_STATE = {"TAKEOFF": "arm", "TRACK": "start_offboard", "LAND": "land"}
# -- faults ----------------------------------------------------------------------------------------


@dataclass
class Injection:
    """What a fault can reach when it is injected."""

    vehicle: FaultyVehicle
    runner: MissionRunner
    state: str
    clock: LoopClock
    later: list[asyncio.Task[None]] = field(default_factory=list)

    def after_s(self, dt_s: float, fn: Callable[[], None]) -> None:
        async def go() -> None:
            await self.clock.sleep(dt_s)
            fn()

        self.later.append(asyncio.get_running_loop().create_task(go()))


@dataclass(frozen=True)
class Fault:
    name: str
    expect: frozenset[str]  # the outcomes that are right for it
    at_s: dict[str, float]  # after the state's entry, per state
    inject: Callable[[Injection], None]
    setup: Callable[[FaultyVehicle, str], None] | None = None  # before the mission starts
    expect_in: dict[tuple[Profile | None, str], frozenset[str]] = field(default_factory=dict)

    def expected(self, profile: Profile, state: str) -> frozenset[str]:
        return self.expect_in.get((profile, state)) or self.expect_in.get((None, state)) or self.expect


def _pilot_switch(i: Injection) -> None:
    i.vehicle.pilot_set_mode(FlightMode.POSCTL)
    i.after_s(4.0, lambda: i.vehicle.pilot_set_mode(FlightMode.LAND))


def _failsafe(mode: FlightMode) -> Callable[[FaultyVehicle, str], None]:
    def setup(v: FaultyVehicle, state: str) -> None:
        v.after[COMMAND_OF_STATE[state]] = lambda: v.autopilot_failsafe(mode)

    return setup


def _nothing(i: Injection) -> None:
    pass


def _nan_burst(i: Injection) -> None:
    i.vehicle.nan_until_s = i.clock.now_s() + 1.0


def _delay(i: Injection) -> None:
    i.vehicle.delay_s = 0.2


def _set(attr: str) -> Callable[[Injection], None]:
    def inject(i: Injection) -> None:
        setattr(i.vehicle, attr, True)

    return inject


AT = {"TAKEOFF": 1.5, "TRACK": 5.0, "LAND": 1.0}
AT_ONCE = {"TAKEOFF": 0.0, "TRACK": 0.0, "LAND": 0.0}
COMPLETED, ABORTED, PILOT = frozenset({"completed"}), frozenset({"aborted"}), frozenset({"pilot"})

FAULTS: tuple[Fault, ...] = (
    Fault("pilot_switch", PILOT, AT, _pilot_switch),
    Fault("gcs_abort", ABORTED, AT, lambda i: i.runner.request_abort("ground station")),
    Fault(
        "abort_in_slow_command",
        ABORTED,
        {"TAKEOFF": 1.0, "TRACK": 1.0, "LAND": 1.0},
        lambda i: i.runner.request_abort("ground station"),
        lambda v, s: v.slow_s.__setitem__(SLOW_COMMAND_OF_STATE[s], 2.0),
    ),
    Fault("command_refused", ABORTED, AT_ONCE, _nothing, lambda v, s: v.refuse.add(COMMAND_OF_STATE[s])),
    # ArduCopter is in GUIDED since its takeoff: an ignored GUIDED command in TRACK changes nothing.
    Fault(
        "mode_never_confirmed",
        ABORTED,
        AT_ONCE,
        _nothing,
        lambda v, s: v.ignore.add(COMMAND_OF_STATE[s]),
        {(Profile.ARDUPILOT, "TRACK"): COMPLETED},
    ),
    Fault("rtl_failsafe", PILOT, AT_ONCE, _nothing, _failsafe(FlightMode.RETURN_TO_LAUNCH)),
    # A LAND failsafe right after our own LAND command shows the mode we asked for: the landing completes.
    Fault("land_failsafe", PILOT, AT_ONCE, _nothing, _failsafe(FlightMode.LAND), {(None, "LAND"): COMPLETED}),
    Fault("position_lost", ABORTED, AT, _set("position_frozen")),
    Fault("heartbeat_lost", ABORTED, AT, _set("heartbeat_lost")),
    Fault("link_lost", ABORTED, AT, lambda i: i.vehicle.lose_link()),
    Fault("delay_200ms", COMPLETED, {"TAKEOFF": 0.0, "TRACK": 0.0, "LAND": 0.0}, _delay),
    Fault("loop_stall_1s", COMPLETED, AT, lambda i: stall_loop(1.0)),
    Fault("nan_telemetry_1s", COMPLETED, AT, _nan_burst),
)


@dataclass(frozen=True)
class Case:
    profile: Profile
    state: str
    fault: str

    @property
    def name(self) -> str:
        return f"{self.profile.value.lower()}/{self.state}/{self.fault}"


@dataclass
class CaseResult:
    case: str
    outcome: str
    reason: str
    injected_at_s: float | None
    violations: list[dict[str, str]]
    setpoints: int
    commands: int
    mission_s: float


def all_cases() -> list[Case]:
    return [Case(p, s, f.name) for p in (Profile.PX4, Profile.ARDUPILOT) for s in FLYING_STATES for f in FAULTS]


def one_lap(table: MissionTable) -> MissionTable:
    return table.model_copy(update={"params": table.params.model_copy(update={"circle_laps": 1.0})})


def limits_of(settings: Settings) -> Limits:
    e, g = settings.envelope, settings.guidance
    return Limits(
        e.max_horizontal_speed_mps, e.max_climb_speed_mps, e.max_descent_speed_mps, g.exit_zero_s, g.watchdog_timeout_s
    )


async def fly_case(case: Case, log_dir: Path, seed: int = 1) -> CaseResult:
    """Fly one case on the running (looptime) loop and check the rules."""
    fault = next(f for f in FAULTS if f.name == case.fault)
    vehicle = FaultyVehicle(seed=seed, profile=case.profile)
    if fault.setup is not None:
        fault.setup(vehicle, case.state)
    settings, clock = Settings(), LoopClock()
    log_path = log_dir / (case.name.replace("/", "_") + ".jsonl")
    log_path.unlink(missing_ok=True)
    events = EventLog(log_path)
    injected: list[float] = []
    tasks: list[asyncio.Task[None]] = []
    injection: list[Injection] = []

    async def inject(runner: MissionRunner) -> None:
        while runner.state != case.state:
            if runner.states_visited and runner.state in ("DONE", "ABORT", "FAILED"):
                return
            await clock.sleep(0.01)
        await clock.sleep(fault.at_s[case.state])
        if runner.state != case.state and fault.at_s[case.state] > 0:
            return
        injected.append(clock.now_s())
        i = Injection(vehicle, runner, case.state, clock)
        injection.append(i)
        fault.inject(i)

    def on_start(runner: MissionRunner) -> None:
        tasks.append(asyncio.get_running_loop().create_task(inject(runner)))

    t0 = clock.now_s()
    violations: list[Violation] = []
    outcome, reason = "error", ""
    try:
        async with asyncio.timeout(CASE_LIMIT_S):
            flight = await fly_mission(vehicle, one_lap(load_mission("circle")), settings, clock, events, on_start)
        outcome, reason = flight.result.outcome, flight.result.reason
        await clock.sleep(SETTLE_S)
        vehicle.truth()
    except TimeoutError:
        violations.append(Violation("safe_end", f"still running after {CASE_LIMIT_S:g} s"))
    finally:
        for t in tasks + [t for i in injection for t in i.later]:
            t.cancel()
        events.close()
    mission_s = clock.now_s() - t0
    lines = [json.loads(x) for x in log_path.read_text().splitlines()]
    abort_t = next((r["t_s"] for r in lines if r["kind"] == "state" and r["to"] == "ABORT"), None)
    if not injected:
        violations.append(Violation("injected", f"the mission never stayed in {case.state} long enough"))
    facts = RunFacts(
        outcome,
        reason,
        fault.expected(case.profile, case.state),
        abort_t,
        len(lines),
        events.total(),
        grace_s=vehicle.delay_s + 0.06,
        end_t_s=clock.now_s(),
    )
    violations += check(vehicle.records, facts, limits_of(settings))
    return CaseResult(
        case.name,
        outcome,
        reason,
        injected[0] - t0 if injected else None,
        [{"case": case.name, "rule": v.rule, "detail": v.detail} for v in violations],
        sum(1 for r in vehicle.records if r["event"] == "setpoint"),
        sum(1 for r in vehicle.records if r["event"] == "command"),
        mission_s,
    )


def run_case(case: Case, log_dir: Path) -> CaseResult:
    """One case on its own looptime loop (in this process)."""
    loop = looptime.new_event_loop(noop_cycles=NOOP_CYCLES)
    try:
        return loop.run_until_complete(fly_case(case, log_dir))
    finally:
        loop.close()


def run_matrix(cases: list[Case], log_dir: Path, jobs: int) -> list[CaseResult]:
    if jobs <= 1:
        return [run_case(c, log_dir) for c in cases]
    with concurrent.futures.ProcessPoolExecutor(jobs) as pool:
        return list(pool.map(run_case, cases, [log_dir] * len(cases)))


def table(results: list[CaseResult]) -> str:
    rows = [f"{'case':44} {'result':6} {'outcome':10} {'reason'}"]
    for r in results:
        mark = "ok" if not r.violations else "FAIL"
        rows.append(f"{r.case:44} {mark:6} {r.outcome:10} {r.reason[:70]}")
        rows += [f"    ! {v['rule']}: {v['detail']}" for v in r.violations]
    passed = sum(1 for r in results if not r.violations)
    rows.append(f"{passed}/{len(results)} cases passed, {sum(len(r.violations) for r in results)} violations")
    return "\n".join(rows)


def main(argv: list[str] | None = None) -> int:
    ap = OneLineParser(
        prog="python -m sim.faults",
        description="Fly the circle mission in virtual time with one fault per flying state and check the "
        "safety rules from the simulated vehicle's side.",
    )
    ap.add_argument("--json", action="store_true", help="print one JSON object (cases, passed, violations)")
    ap.add_argument("--jobs", type=int, default=os.cpu_count() or 1, help="processes to run cases in (default: cores)")
    ap.add_argument("--only", default="", help="run only the cases whose name contains this text")
    ap.add_argument("--keep", type=Path, default=None, help="keep the event logs in this directory")
    args = ap.parse_args(argv)
    if args.jobs < 1:
        ap.error(f"--jobs must be ≥ 1, got {args.jobs}")
    cases = [c for c in all_cases() if args.only in c.name]
    if not cases:
        ap.error(f"no case matches --only {args.only!r}")
    with tempfile.TemporaryDirectory(prefix="seapick-faults-") as tmp:
        log_dir = args.keep or Path(tmp)
        try:
            log_dir.mkdir(parents=True, exist_ok=True)
        except OSError as e:
            ap.error(f"--keep {log_dir}: {e.strerror}")
        results = run_matrix(cases, log_dir, args.jobs)
    passed = sum(1 for r in results if not r.violations)
    if args.json:
        violations = [v for r in results for v in r.violations]
        doc = {
            "cases": len(results),
            "passed": passed,
            "violations": violations,
            "results": [asdict(r) for r in results],
        }
        print(json.dumps(doc, indent=1))
    else:
        print(table(results))
    return 0 if passed == len(results) else 1


if __name__ == "__main__":
    sys.exit(run_cli(main, "python -m sim.faults"))
