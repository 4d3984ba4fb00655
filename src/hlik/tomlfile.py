"""Reading hlik's TOML inputs (stacks, metrics, approach files) with one-line errors."""

from __future__ import annotations

import sys
from collections.abc import Sequence
from pathlib import Path

from hlik.errors import HlikError

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib


def read_toml(path: Path, what: str, bundled: Sequence[str] = ()) -> dict:
    """The table of the TOML file ``path``, a ``what`` file (``stack``, ``metric``, ...).

    Raises:
        HlikError: ``"<path>: no such <what> file"`` (listing ``bundled`` names if any), cannot
            read, or not valid TOML.
    """
    try:
        return tomllib.loads(Path(path).read_text(encoding="utf-8"))
    except FileNotFoundError:
        known = f" (bundled: {', '.join(bundled)})" if bundled else ""
        raise HlikError(f"{path}: no such {what} file{known}") from None
    except (OSError, UnicodeDecodeError) as e:
        raise HlikError(f"{path}: cannot read ({e})") from None
    except tomllib.TOMLDecodeError as e:
        raise HlikError(f"{path}: not valid TOML ({e})") from None
