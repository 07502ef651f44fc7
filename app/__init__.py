"""seapick: find, land on and pick up a small object floating at sea."""

import os

# The app's matrices are small (its filters have at most a few dozen states): BLAS threads only add wake-ups,
# and the event loop's thread, under SCHED_FIFO (``guidance.realtime_priority``), waited in scipy's expm for
# OpenBLAS workers that a busy process kept off the CPU — setpoint gaps of 0.1–0.2 s. Set before numpy or scipy
# loads its BLAS; a value the user set wins.
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
