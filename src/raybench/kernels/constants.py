"""The float32 constants every kernel reads, defined once. Module globals
(imported into each kernel's module), which is how Numba's and numba-cuda's
compiled functions see them: as constants."""

import numpy as np

ZERO = np.float32(0.0)
ONE = np.float32(1.0)
HALF = np.float32(0.5)
TWO = np.float32(2.0)
# Farther than any hit: the validated scene keeps coordinates under 1e15.
FAR = np.float32(3.0e38)
