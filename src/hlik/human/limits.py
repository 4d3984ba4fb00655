"""What hlik accepts of a motion's time base and of its subject's scale, as plain numbers (no
NumPy), so that a ``--rate`` or a ``--scale`` is checked before anything heavy loads."""

from __future__ import annotations

import math

from hlik.util.errors import SettingsError

# Frame rates a motion may have, Hz: below, it is no motion capture; above, the timesteps are not
# seconds (or not a clock at all).
RATE_RANGE = (1.0, 10_000.0)
# Most frames a resampled motion may have: a run needs about 1.1 GB per 60 000 frames (issue 15),
# so 10^6 frames would need some 18 GB.
MAX_FRAMES = 1_000_000
# Subject scale factors: outside, a typo, not a robot.
SCALE_RANGE = (0.1, 10.0)


def scale_factor(rule: float | str) -> float | None:
    """The factor of a subject scale rule (``--scale``, ``subject_scale``): a number within
    :data:`SCALE_RANGE`, or None for ``"auto"``.

    Raises:
        SettingsError: a rule that is neither ``auto`` nor a factor in range (one line).
    """
    if rule == "auto":
        return None
    try:
        factor = float(rule)
    except (TypeError, ValueError):
        factor = math.nan
    if not SCALE_RANGE[0] <= factor <= SCALE_RANGE[1]:  # NaN fails both
        low, high = SCALE_RANGE
        raise SettingsError(
            f"subject scale (--scale, subject_scale) must be auto or {low:g}-{high:g}, got {rule!r}"
        )
    return factor
