"""What hlik accepts of a motion's time base, as plain numbers (no NumPy), so that a ``--rate``
is checked before anything heavy loads."""

from __future__ import annotations

# Frame rates a motion may have, Hz: below, it is no motion capture; above, the timesteps are not
# seconds (or not a clock at all).
RATE_RANGE = (1.0, 10_000.0)
# Most frames a resampled motion may have: a run needs about 1.1 GB per 60 000 frames (issue 15),
# so 10^6 frames would need some 18 GB.
MAX_FRAMES = 1_000_000
