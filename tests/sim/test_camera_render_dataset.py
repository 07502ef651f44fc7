"""The perception data set: PNG frames and a truth file that agree with each other."""

from __future__ import annotations

import json
from pathlib import Path

import cv2
import numpy as np
import pytest

from sim.camera_dataset import VERSION, main


def test_dataset_cli_writes_frames_and_truth(tmp_path: Path) -> None:
    assert (
        main(["--out", str(tmp_path), "--seed", "3", "--scenes", "2", "--frames-per-scene", "2", "--empty", "1"]) == 0
    )
    doc = json.loads((tmp_path / "truth.json").read_text())
    assert doc["version"] == VERSION and doc["seed"] == 3 and doc["camera"]["width_px"] == 1280
    frames = doc["frames"]
    assert [f["marker"] for f in frames] == [True, True, True, True, False]
    assert [(f["scene"], f["index"]) for f in frames[:4]] == [(0, 0), (0, 1), (1, 0), (1, 1)]
    assert frames[1]["t_s"] - frames[0]["t_s"] == pytest.approx(1 / doc["fps_hz"])
    for f in frames:
        image = cv2.imread(str(tmp_path / f["file"]), cv2.IMREAD_GRAYSCALE)
        assert image is not None and image.shape == (960, 1280)
        if f["marker"]:
            corners = np.array(f["corners_px"])
            assert np.all((corners >= 0) & (corners < [1280, 960]))
            assert np.allclose(corners.mean(axis=0), f["center_px"])
            assert 15.0 <= f["size_px"] <= 450.0
            # the marker's black border lies just inside its corners
            for corner in corners:
                x, y = np.round(corner + 0.15 * (corners.mean(axis=0) - corner)).astype(int)
                assert image[y, x] < 100
        else:
            assert "corners_px" not in f
