"""The arrays of an ``.npy`` or ``.npz`` file, their shapes read from the headers before any data:
a header can claim any shape (``(1e7, 1e6)``), and an ``.npz`` member can inflate to gigabytes from
a few megabytes of zeros, so what is read is checked first."""

from __future__ import annotations

import zipfile
from pathlib import Path
from typing import IO

import numpy as np

MAX_BYTES = 2 * 1024**3  # the most hlik reads into memory from one array file


def _header(fp: IO[bytes]) -> tuple[tuple[int, ...], np.dtype]:
    version = np.lib.format.read_magic(fp)
    if version == (1, 0):
        shape, _, dtype = np.lib.format.read_array_header_1_0(fp)
    else:
        shape, _, dtype = np.lib.format.read_array_header_2_0(fp)
    return shape, dtype


def array_shapes(path: Path) -> dict[str, tuple[int, ...]]:
    """Name -> shape of every array in ``path`` (``.npy``: one, named ``""``), from the headers.

    Raises:
        ValueError: a header that is not NumPy's, or arrays larger than :data:`MAX_BYTES`
            (by their headers, or an ``.npz`` member's inflated size); the message names the array.
    """
    shapes = {}
    if path.suffix.lower() == ".npz":
        with zipfile.ZipFile(path) as archive:
            for info in archive.infolist():
                name = info.filename.removesuffix(".npy")
                if info.file_size > MAX_BYTES:
                    raise ValueError(
                        f"array {name!r} inflates to {info.file_size / 1e9:.2g} GB, more than hlik reads"
                    )
                with archive.open(info) as fp:
                    shapes[name] = _check(name, *_header(fp))
    else:
        with open(path, "rb") as fp:
            shapes[""] = _check("", *_header(fp))
    return shapes


def _check(name: str, shape: tuple[int, ...], dtype: np.dtype) -> tuple[int, ...]:
    size = int(np.prod(shape, dtype=object)) * max(dtype.itemsize, 8)  # read as float64
    if size > MAX_BYTES:
        what = f"array {name!r}" if name else "the array"
        claim = f"shape {shape} ({size / 1e9:.3g} GB)"
        raise ValueError(f"{what}: its header claims {claim}, more than hlik reads")
    return shape
