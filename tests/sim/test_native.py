"""The simulator's compiled modules (``sim.native``): used only when fresh, and a run flies the same either way."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from sim import native

# one evaluation run (seed 1, sea state 3, run 0: waves, wind, an estimator with errors), its result as JSON, and
# whether the compiled modules flew it
FLY = """
import json, sim.native
from sim.evaluate_pickup import run_pickup
from sim.pickup_scenarios import sample_scenarios
r = run_pickup(sample_scenarios(1, 1, 3)[0], "seapick", 0)
r.pop("wall_s")
print(json.dumps({"native": sim.native.active(), "result": r}, sort_keys=True))
"""


def _fly(native_on: bool) -> dict:
    env = dict(os.environ, SEAPICK_NATIVE="1" if native_on else "0")
    out = subprocess.run([sys.executable, "-c", FLY], env=env, capture_output=True, text=True, check=True, timeout=300)
    return json.loads(out.stdout.strip().splitlines()[-1])


@pytest.mark.skipif(not native.is_fresh(), reason="no fresh build in build/native (`make native`; needs a C compiler)")
def test_a_run_flies_the_same_compiled_and_as_plain_python() -> None:
    compiled, plain = _fly(True), _fly(False)
    assert compiled["native"] is True and plain["native"] is False
    assert compiled["result"]["mission_s"] > 30.0  # a whole mission, not an early error
    assert compiled["result"] == plain["result"]


def test_a_build_is_used_only_while_it_matches_the_sources(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv("SEAPICK_NATIVE", raising=False)
    built = native.manifest()
    (tmp_path / "manifest.json").write_text(json.dumps(built))
    assert native.is_fresh(tmp_path)
    # one source edited since the build
    edited = dict(built, sources=dict(built["sources"], **{"sim/dynamics.py": "0" * 64}))  # type: ignore[arg-type]
    (tmp_path / "manifest.json").write_text(json.dumps(edited))
    assert not native.is_fresh(tmp_path)
    path: list[str] = ["src"]
    assert native.activate(path, tmp_path) is False and path == ["src"]
    # another interpreter's build
    (tmp_path / "manifest.json").write_text(json.dumps(dict(built, python="3.11.2 (main) /usr/bin/python3.11")))
    assert not native.is_fresh(tmp_path)
    # no build at all, or a torn manifest
    (tmp_path / "manifest.json").write_text('{"cache_tag": ')
    assert not native.is_fresh(tmp_path)
    assert not native.is_fresh(tmp_path / "none")


def test_seapick_native_0_keeps_a_fresh_build_off(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    (tmp_path / "manifest.json").write_text(json.dumps(native.manifest()))
    monkeypatch.setattr(sys, "path", list(sys.path))  # activate() appends the build's directory
    path: list[str] = ["src"]
    monkeypatch.setenv("SEAPICK_NATIVE", "0")
    assert native.activate(path, tmp_path) is False and path == ["src"]
    monkeypatch.setenv("SEAPICK_NATIVE", "1")
    assert native.activate(path, tmp_path) is True and path == [str(tmp_path / "sim"), "src"]


def test_a_failed_build_says_why_and_leaves_no_build(tmp_path: Path) -> None:
    from sim import native_build

    root = tmp_path / "src"
    for m in native.MODULES:
        (root / m).parent.mkdir(parents=True, exist_ok=True)
        (root / m).write_bytes((native.ROOT / m).read_bytes())
    (root / "sim/wind.py").write_text("def broken(:\n")  # a syntax error: mypyc stops at it
    out = tmp_path / "native"
    with pytest.raises(RuntimeError, match=r"mypyc failed \(exit [1-9]"):
        native_build.build(out, root)
    assert not out.exists() and not native.is_fresh(out, root)
