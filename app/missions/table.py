"""The mission as a declarative table, loaded from YAML and validated before anything connects.

A table has ``mission`` (name), ``initial`` (state), ``params`` (``MissionParams``) and ``states``. A state:

    control:     none | autopilot | offboard   (autopilot/offboard = flying: the mission commands it)
    entry:       [action, ...]                  run in order on entry
    transitions: [{when: guard, to: STATE}]     first true guard wins, checked every tick; a flying state
                                                needs abort_requested, link_lost, position_lost and
                                                setpoints_failing (``guards.LINK_GUARDS``)
    timeout_s / on_timeout                      required for every flying state and for MANUAL
    terminal:    completed | picked_up | aborted | failed | pilot   (the run's outcome; no transitions)
    manual: true                                the state the runner enters when the pilot takes over
    resume: {STATE: STATE}, resume_default      (manual, and the hold request's state) where to go when control is
                                                handed back, or on a resume request
  requests: {hold: STATE, rtl: STATE}           ground-station requests, honoured in every flying state
    abort: true                                 marks the ABORT state

Errors name the YAML path, e.g. ``states.TRACK.transitions[1].when: unknown guard 'laps'``.
"""

from __future__ import annotations

from pathlib import Path
from typing import Literal

from pydantic import BaseModel, ConfigDict, Field, ValidationError

from app.config_yaml import format_validation_error, load_yaml
from app.errors import MissionTableError
from app.missions.actions import ACTIONS
from app.missions.guards import GUARDS, LINK_GUARDS
from app.missions.params import MissionParams

MISSIONS_DIR = Path(__file__).resolve().parent

Control = Literal["none", "autopilot", "offboard"]
Outcome = Literal["completed", "picked_up", "aborted", "failed", "pilot"]
SUCCESS: frozenset[str] = frozenset({"completed", "picked_up"})  # outcomes that exit 0


class _Model(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


class TransitionSpec(_Model):
    when: str = Field(description="guard name")
    to: str = Field(description="target state")


class StateSpec(_Model):
    control: Control = "none"
    entry: tuple[str, ...] = ()
    transitions: tuple[TransitionSpec, ...] = ()
    timeout_s: float | None = Field(None, gt=0.0, le=86400.0, description="time limit in this state, s")
    on_timeout: str | None = None
    terminal: Outcome | None = None
    manual: bool = False
    abort: bool = False
    resume: dict[str, str] = {}
    resume_default: str | None = None

    @property
    def flying(self) -> bool:
        return self.control != "none"


class MissionTable(_Model):
    mission: str
    description: str = ""
    initial: str
    params: MissionParams = MissionParams()
    states: dict[str, StateSpec]
    # ground-station requests honoured in every flying state (the pilot and ABORT still win): hold → the state
    # that holds (it resumes through its ``resume`` map), rtl → the state that brings the vehicle home
    requests: dict[Literal["hold", "rtl"], str] = {}

    @property
    def manual_state(self) -> str:
        return next(name for name, s in self.states.items() if s.manual)

    @property
    def abort_state(self) -> str:
        return next(name for name, s in self.states.items() if s.abort)

    def to_mermaid(self) -> str:
        """The table as a Mermaid state diagram (for docs and reports)."""
        lines = ["stateDiagram-v2", f"    [*] --> {self.initial}"]
        for name, s in self.states.items():
            for t in s.transitions:
                lines.append(f"    {name} --> {t.to}: {t.when}")
            if s.on_timeout:
                lines.append(f"    {name} --> {s.on_timeout}: timeout {s.timeout_s:g} s")
            for src, dst in s.resume.items():
                lines.append(f"    {name} --> {dst}: handed back (from {src})")
            if s.terminal:
                lines.append(f"    {name} --> [*]")
        return "\n".join(lines)


def resolve_mission_path(name_or_path: str) -> Path:
    """A path as given, else a file in ``app/missions`` (``circle`` or ``circle.yaml``)."""
    p = Path(name_or_path)
    if p.exists():
        return p
    candidate = MISSIONS_DIR / (p.name if p.suffix else p.name + ".yaml")
    if candidate.exists():
        return candidate
    known = sorted(f.stem for f in MISSIONS_DIR.glob("*.yaml"))
    raise MissionTableError(name_or_path, "", f"no such mission file; built-in missions: {', '.join(known)}")


def load_mission(name_or_path: str) -> MissionTable:
    path = resolve_mission_path(name_or_path)
    data = load_yaml(path)
    try:
        table = MissionTable.model_validate(data)
    except ValidationError as e:
        err = format_validation_error(str(path), e, MissionTable)
        raise MissionTableError(err.source, err.path, err.message) from e
    validate_table(table, str(path))
    return table


def validate_table(table: MissionTable, source: str) -> None:
    """Semantic checks; raises ``MissionTableError`` naming the first offending YAML path."""

    def fail(path: str, message: str) -> None:
        raise MissionTableError(source, path, message)

    states = table.states
    names = sorted(states)

    def check_state_ref(path: str, name: str | None) -> None:
        if name is not None and name not in states:
            fail(path, f"unknown state {name!r}; states: {', '.join(names)}")

    check_state_ref("initial", table.initial)
    for request, target in table.requests.items():
        check_state_ref(f"requests.{request}", target)
        if not states[target].flying:
            fail(f"requests.{request}", f"{target!r} does not fly: a request leads to a flying state")
    manuals = [n for n, s in states.items() if s.manual]
    aborts = [n for n, s in states.items() if s.abort]
    if len(aborts) != 1:
        fail("states", f"exactly one state needs 'abort: true' (found {len(aborts)})")
    if len(manuals) != 1:
        fail("states", f"exactly one state needs 'manual: true' (found {len(manuals)})")
    if not any(s.terminal in SUCCESS for s in states.values()):
        fail("states", "no state has 'terminal: completed' (or picked_up)")

    for name, s in states.items():
        base = f"states.{name}"
        for i, action in enumerate(s.entry):
            spec = ACTIONS.get(action)
            if spec is None:
                fail(f"{base}.entry[{i}]", f"unknown action {action!r}; known: {', '.join(sorted(ACTIONS))}")
            elif spec.control is not None and s.control not in spec.control:
                fail(f"{base}.entry[{i}]", f"action {action!r} needs control {' or '.join(spec.control)}")
        for i, t in enumerate(s.transitions):
            if t.when not in GUARDS:
                fail(f"{base}.transitions[{i}].when", f"unknown guard {t.when!r}; known: {', '.join(sorted(GUARDS))}")
            check_state_ref(f"{base}.transitions[{i}].to", t.to)
        check_state_ref(f"{base}.on_timeout", s.on_timeout)
        if (s.timeout_s is None) != (s.on_timeout is None):
            fail(f"{base}.timeout_s", "timeout_s and on_timeout go together")
        for src, dst in s.resume.items():
            check_state_ref(f"{base}.resume", src)
            check_state_ref(f"{base}.resume.{src}", dst)
        check_state_ref(f"{base}.resume_default", s.resume_default)
        if (s.resume or s.resume_default) and not s.manual and name != table.requests.get("hold"):
            fail(f"{base}.resume", "only the manual state and the hold request's state resume")
        if s.terminal is not None:
            if s.transitions or s.on_timeout:
                fail(f"{base}.terminal", "a terminal state has no transitions or timeout")
            continue
        if s.manual:
            if s.control != "none":
                fail(f"{base}.control", "the manual state commands nothing: control must be none")
            if not s.resume and not s.resume_default:
                fail(f"{base}.resume", "the manual state needs resume or resume_default")
        if not s.transitions and not s.on_timeout:
            fail(base, "a non-terminal state needs a transition or a timeout")
        if s.flying or s.manual:
            if s.timeout_s is None:
                fail(f"{base}.timeout_s", "every flying state (and the manual state) needs a timeout")
        if s.flying:
            exits = [t.to for t in s.transitions] + [s.on_timeout]
            if not any(e is not None and states[e].abort for e in exits):
                fail(base, f"flying state has no way to ABORT: add a transition or on_timeout to {aborts[0]!r}")
            missing = [g for g in LINK_GUARDS if g not in {t.when for t in s.transitions}]
            if missing:
                fail(f"{base}.transitions", f"a flying state needs the guards {', '.join(missing)}")
        for i, t in enumerate(s.transitions):
            if t.when == "abort_requested" and not states[t.to].abort:
                fail(f"{base}.transitions[{i}].to", f"abort_requested must lead to the abort state {aborts[0]!r}")

    # Reachability: from the initial state along transitions, timeouts and resumes; the manual state
    # is reachable from every flying state (the pilot can take over anywhere).
    reached: set[str] = set()
    todo = [table.initial]
    while todo:
        name = todo.pop()
        if name in reached:
            continue
        reached.add(name)
        s = states[name]
        nxt = [t.to for t in s.transitions] + ([s.on_timeout] if s.on_timeout else [])
        nxt += list(s.resume.values()) + ([s.resume_default] if s.resume_default else [])
        if s.flying:
            nxt.append(manuals[0])
            nxt += list(table.requests.values())
        todo.extend(n for n in nxt if n not in reached)
    unreachable = [n for n in names if n not in reached]
    if unreachable:
        fail(f"states.{unreachable[0]}", f"unreachable from {table.initial!r}")
