"""A file named on the command line, checked to be there and readable before anything heavy loads
(a missing trajectory costs no NumPy, MuJoCo or SciPy import)."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path


def check_readable(path: Path, error: Callable[[str], Exception], expected: str, head: int = 0) -> bytes:
    """The first ``head`` bytes of ``path``; raises ``error(problem)`` unless it is a file this
    process can open.

    Args:
        path: The file.
        error: Makes the caller's exception of the problem (``no such file``, ...), which it
            prefixes with the file's name.
        expected: What the file should be, for the folder case (``a trajectory .npz file``).
        head: How many bytes to read (0: none).
    """
    try:
        with path.open("rb") as f:
            return f.read(head) if head else b""
    except FileNotFoundError:
        raise error("no such file") from None
    except IsADirectoryError:
        raise error(f"is a folder, expected {expected}") from None
    except OSError as e:
        raise error(f"cannot read ({e.strerror})") from None
