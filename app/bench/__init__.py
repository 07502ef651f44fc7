"""Benchmarks: ``python -m app.bench {perception,triangulation,radar} [--json]``.

Each prints the measured figures (median, p95, ratio against a baseline measured in the same run) and,
with ``--json``, one JSON object on stdout. ``app`` never imports ``sim``: where a benchmark needs synthetic
data from the simulator, it runs ``python -m sim....`` as a subprocess that writes the data set to disk.
"""
