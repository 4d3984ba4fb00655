"""A file named on the command line, checked to be there and readable before anything heavy loads
(a missing trajectory costs no NumPy, MuJoCo or SciPy import)."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path


def check_readable(path: Path, error: Callable[[str], Exception], expected: str) -> None:
    """Raise ``error(message)`` unless ``path`` is a file this process can open.

    Args:
        path: The file.
        error: The exception class (or factory) of the caller's part, given the one-line message.
        expected: What the file should be, for the folder case (``a trajectory .npz file``).
    """
    try:
        with path.open("rb"):
            pass
    except FileNotFoundError:
        raise error(f"{path}: no such file") from None
    except IsADirectoryError:
        raise error(f"{path}: is a folder, expected {expected}") from None
    except OSError as e:
        raise error(f"{path}: cannot read ({e.strerror})") from None
