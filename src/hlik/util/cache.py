"""Disk cache entries that prove themselves: each carries its key and a checksum of its arrays.

Learned pieces (:mod:`hlik.criteria.learned`) and reachability maps (:mod:`hlik.robot.reachability`)
are cached as ``.npz`` files in :func:`hlik.util.paths.cache_dir`. An entry is trusted only if it is
whole, matches its checksum and was written for the same key (format, robot, a hash of the model,
what it was made from); otherwise the caller makes it again and says so in one line.
"""

from __future__ import annotations

import hashlib
import re
import zipfile
import zlib
from collections.abc import Mapping
from pathlib import Path

import numpy as np

from hlik.util.atomic import atomic_path
from hlik.util.paths import cache_dir

ENTRY = "entry."  # prefix of the arrays holding a cache entry's key and checksum
# What np.load raises on a truncated or damaged archive (zip, zlib and npy errors).
UNREADABLE = (OSError, EOFError, ValueError, KeyError, TypeError, zipfile.BadZipFile, zlib.error)
_LABELS = {"model": "robot model", "corpus": "corpus and human model"}


def entry_path(stem: str, key: Mapping[str, str]) -> Path:
    """``<cache>/<stem>-<digest of key>.npz``; characters a file name must not hold become ``_``."""
    digest = hashlib.sha256(repr(sorted(key.items())).encode()).hexdigest()[:16]
    return cache_dir() / f"{re.sub(r'[^A-Za-z0-9_.+-]', '_', stem)}-{digest}.npz"


def checksum(arrays: Mapping[str, np.ndarray]) -> str:
    """SHA-256 hex digest of named arrays: names, dtypes, shapes and bytes, in name order."""
    digest = hashlib.sha256()
    for name in sorted(arrays):
        a = np.ascontiguousarray(arrays[name])
        digest.update(f"{name}\0{a.dtype.str}\0{a.shape}\0".encode())
        digest.update(a.tobytes())
    return digest.hexdigest()


def write_entry(
    path: Path, arrays: Mapping[str, np.ndarray], key: Mapping[str, str], compressed: bool = False
) -> str | None:
    """Write ``arrays`` with ``key`` and their checksum to ``path`` atomically.

    Returns:
        None, or a one-line note why nothing was cached (the caller's result stands without it).
    """
    stored = {**arrays, **{ENTRY + k: np.array(v) for k, v in key.items()}}
    stored[ENTRY + "checksum"] = np.array(checksum(stored))
    save = np.savez_compressed if compressed else np.savez
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        with atomic_path(path) as tmp, open(tmp, "wb") as f:
            save(f, **stored)  # type: ignore[arg-type]  # numpy's stub types allow_pickle
    except OSError as e:
        return f"{path}: cannot write the cache entry ({one_line(e)}); not cached"
    return None


def read_entry(path: Path, key: Mapping[str, str]) -> tuple[dict[str, np.ndarray] | None, str | None]:
    """The arrays of the cache entry at ``path`` if it is whole and was written for ``key``.

    Returns:
        (arrays without the key and checksum, None); (None, None) if there is no entry; or
        (None, what is wrong with it), a phrase such as ``does not match its checksum``.
    """
    if not path.exists():
        return None, None
    try:
        with open(path, "rb") as f:
            magic = f.read(4)
            if not magic:
                return None, "is empty"
            if magic != b"PK\x03\x04":  # else NumPy would try it as .npy or pickle
                return None, "is not an .npz archive"
            f.seek(0)
            with np.load(f, allow_pickle=False) as z:
                arrays = {k: z[k] for k in z.files}
    except OSError as e:
        return None, f"is unreadable ({one_line(e)})"
    except UNREADABLE as e:
        return None, f"is truncated or damaged ({one_line(e)})"
    stored = arrays.pop(ENTRY + "checksum", None)
    if stored is None or any(ENTRY + k not in arrays for k in key):
        return None, "has no key or checksum (written by an older hlik?)"
    if str(stored) != checksum(arrays):
        return None, "does not match its checksum (edited or damaged)"
    for k, expected in key.items():
        found = str(arrays[ENTRY + k])
        if found != expected:
            if re.fullmatch("[0-9a-f]{64}", expected):  # a digest: its first digits say enough
                found, expected = found[:12] + "...", expected[:12] + "..."
            return None, f"was written for {_LABELS.get(k, k)} {found!r}, not {expected!r}"
    return {k: a for k, a in arrays.items() if not k.startswith(ENTRY)}, None


def one_line(error: BaseException) -> str:
    if isinstance(error, OSError) and error.strerror:
        return error.strerror  # not str(error): it names the temporary file, not the entry
    text = " ".join(str(error).split())
    return f"{type(error).__name__}: {text}" if text else type(error).__name__
