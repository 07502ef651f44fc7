"""``python -m app.bench perception --json``: the JSON contract, on a tiny data set rendered by the simulator."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from app.bench.perception import main


def test_perception_bench_prints_one_json_object_with_the_figures(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    args = ["--json", "--data", str(tmp_path), "--seed", "4", "--scenes", "2", "--frames-per-scene", "2"]
    assert main([*args, "--empty", "1", "--repeat", "1"]) == 0
    result = json.loads(capsys.readouterr().out)
    for key in ("naive_ms_median", "search_ms_median", "track_ms_median", "speedup_track", "recall", "false_fixes"):
        assert key in result
    assert result["frames"] == 5 and result["marker_frames"] == 4
    assert 0.0 <= result["recall"] <= 1.0 and result["false_fixes"] >= 0
    assert result["speedup_track"] == pytest.approx(result["naive_ms_median"] / result["track_ms_median"])
    assert (tmp_path / "truth.json").exists()  # cached for the next run
