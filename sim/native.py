"""The simulator's physics and sea compiled with mypyc: the same source, the same results, less CPU per run.

An evaluation's cost is the simulator's Python (issue 13: 400 runs on 2 cores in under 15 minutes). ``python -m
sim.native_build`` (``make native``, which ``make demo``/``test``/``eval`` run first) compiles ``MODULES`` with mypyc —
as mypy itself ships — into ``build/native/`` (git-ignored), with a manifest of what it compiled from. At import,
``sim/__init__.py`` puts that directory ahead of the sources on ``sim``'s path only while the manifest matches the
sources byte for byte (and the interpreter): a module edited since the build runs as plain Python, never a
stale compiled copy. ``SEAPICK_NATIVE=0`` runs everything as plain Python.

Compiled or not, a run flies the same, bit for bit (IEEE doubles and the C library's ``math`` either way): a test
flies one run both ways and compares. Without a C compiler or Python's headers the build says why and everything
runs as plain Python.
"""

from __future__ import annotations

import hashlib
import json
import os
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
NATIVE_DIR = ROOT / "build" / "native"
GROUP = "seapick_native"  # the shared library's name (``seapick_native__mypyc``), beside the modules' stubs
# the hot loop of an in-process run: vehicle physics, the autopilot's stack, the sea, the geometric camera
MODULES = (
    "sim/noise.py",
    "sim/wind.py",
    "sim/poscontrol.py",
    "sim/multirotor.py",
    "sim/estimator.py",
    "sim/dynamics.py",
    "sim/stack_types.py",
    "sim/navigator.py",
    "sim/land_detector.py",
    "sim/failsafe.py",
    "sim/command_checks.py",
    "sim/autopilot_params.py",
    "sim/flight_stack.py",
    "sim/sea_spectrum.py",
    "sim/sea.py",
    "sim/camera_geometry.py",
)


def manifest(root: Path = ROOT) -> dict[str, object]:
    """What a build is valid for: the interpreter (its version and build, where it runs from) and every compiled
    source's SHA-256. (Not mypy's version: the build carries mypyc's runtime in its own shared library, and
    reading that version costs every ``import sim`` ~40 ms.)"""
    return {
        "python": f"{sys.version} {sys.executable}",
        "sources": {m: hashlib.sha256((root / m).read_bytes()).hexdigest() for m in MODULES},
    }


def is_fresh(native_dir: Path = NATIVE_DIR, root: Path = ROOT) -> bool:
    """Does ``native_dir`` hold a build of the sources as they are now (for this interpreter)?"""
    try:
        built = json.loads((native_dir / "manifest.json").read_text())
    except (OSError, ValueError):
        return False
    try:
        return isinstance(built, dict) and all(built.get(k) == v for k, v in manifest(root).items())
    except OSError:  # a source gone
        return False


def activate(sim_path: list[str], native_dir: Path = NATIVE_DIR) -> bool:
    """Called by ``sim/__init__.py``: the compiled modules ahead of the sources when they are fresh (and
    ``SEAPICK_NATIVE`` is not ``0``). True if they are."""
    if os.environ.get("SEAPICK_NATIVE", "1") == "0" or not is_fresh(native_dir):
        return False
    lib = str(native_dir)
    if lib not in sys.path:
        sys.path.append(lib)  # the shared library, imported by its top-level name
    sim_path.insert(0, str(native_dir / "sim"))
    return True


def active() -> bool:
    """Are ``MODULES`` running compiled in this process?"""
    import sim.dynamics

    return not str(sim.dynamics.__file__).endswith(".py")
