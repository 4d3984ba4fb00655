"""Time-varying data as Rerun columns, chunk by chunk of frames: the types, the time index, scalar
curves and poses."""

from __future__ import annotations

from collections.abc import Callable, Iterator, Mapping
from typing import Any

import numpy as np
import rerun as rr
from scipy.spatial.transform import Rotation

# One entity's columns for some frames: (entity path, time columns, component columns).
Columns = tuple[str, list[rr.TimeColumn], Any]
# The time-varying data of one or more entities: frames (a slice of the take) -> their columns.
Track = Callable[[slice], Iterator[Columns]]
# A scalar curve: (T,) values, or the values of the frames (a slice).
Curve = np.ndarray | Callable[[slice], np.ndarray]


def _curve(rec, entity: str, name: str, color=None) -> str:
    """Log the style of a scalar curve at ``entity``; returns ``entity``."""
    style = rr.SeriesLines(names=name) if color is None else rr.SeriesLines(names=name, colors=[color])
    rec.log(entity, style, static=True)
    return entity


def _error(error: Callable, a: np.ndarray, b: np.ndarray) -> Callable[[slice], np.ndarray]:
    """The curve ``error(a[rows], b[rows])`` of the frames ``rows``."""
    return lambda rows: error(a[rows], b[rows])


def _curve_columns(curves: Mapping[str, Curve], times: np.ndarray, rows: slice) -> Iterator[Columns]:
    """The track of scalar curves."""
    index = _index(times, rows)
    for entity, values in curves.items():
        scalars = values(rows) if callable(values) else values[rows]
        yield entity, index, rr.Scalars.columns(scalars=scalars)


def _index(times: np.ndarray, rows: slice) -> list[rr.TimeColumn]:
    """The ``frame`` and ``time`` columns of the frames ``rows`` (a slice with start and stop)."""
    return [
        rr.TimeColumn("frame", sequence=np.arange(rows.start, rows.stop)),
        rr.TimeColumn("time", duration=times[rows]),
    ]


def _pose_columns(pos: np.ndarray, rot: np.ndarray):
    """Transform columns from (T, 3) positions and (T, 3, 3) rotations."""
    return rr.Transform3D.columns(translation=pos, quaternion=Rotation.from_matrix(rot).as_quat())


def _entity(name: str) -> str:
    return "".join(c if c.isalnum() or c in "_-." else "_" for c in name)
