"""The simulator. Its hot modules run compiled when ``build/native`` holds a fresh build of them (``sim.native``)."""

from sim.native import activate as _activate

_activate(__path__)
