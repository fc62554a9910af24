"""gnss_sim: a GNSS receiver simulator for ROS 2 robots."""
import os as _os

# The solver factorises 8 x 8 matrices a few times per epoch: OpenBLAS spreading each over every core made
# `gnss-sim simulate` of the 1 h demo 10x slower (93 s against 9.4 s, docs/profile-offline-chain.md).  One
# BLAS thread unless the user says otherwise; read by OpenBLAS when numpy loads, so set before any import.
_os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

__version__ = "0.1.0"
