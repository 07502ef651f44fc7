"""Standard normal draws for the simulation's noise processes, taken from numpy a batch at a time.

A step of a gust or an estimator error needs one N(0, 1) per axis; asking numpy for each costs a call into the
generator, a batch turned into Python lists costs one list lookup per step.
"""

from __future__ import annotations

import numpy as np


class NormalBatches:
    """``next()``: ``width`` N(0, 1) draws (a list of floats) from ``rng``, made ``batch`` rows at a time."""

    def __init__(self, rng: np.random.Generator, width: int, batch: int) -> None:
        self._rng, self._width, self._batch = rng, width, batch
        self._rows: list[list[float]] = []
        self._next = 0

    def next(self) -> list[float]:
        if self._next >= len(self._rows):
            self._rows = self._rng.standard_normal((self._batch, self._width)).tolist()
            self._next = 0
        row = self._rows[self._next]
        self._next += 1
        return row
