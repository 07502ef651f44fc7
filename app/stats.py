"""Small summary statistics for run figures (no numpy on the flight path)."""

from __future__ import annotations

from collections.abc import Sequence


def percentile(sorted_xs: Sequence[float], q: float) -> float | None:
    """The ``q`` quantile (0..1) of already sorted values, nearest rank; ``None`` when there are none."""
    if not sorted_xs:
        return None
    return sorted_xs[min(len(sorted_xs) - 1, round(q * (len(sorted_xs) - 1)))]
