"""Reading hlik's TOML inputs (stacks, metrics, approach files, robots) with one-line errors."""

from __future__ import annotations

import sys
from collections.abc import Sequence
from pathlib import Path

from hlik.util.errors import SettingsError

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib


def read_toml(path: Path, what: str, bundled: Sequence[str] = ()) -> dict:
    """The table of the TOML file ``path``, a ``what`` file (``stack``, ``metric``, ...).

    Raises:
        SettingsError: ``"<path>: no such <what> file"`` (listing ``bundled`` names if any), a
            folder, cannot be read (permission), not UTF-8 text, or not valid TOML.
    """
    try:
        data = Path(path).read_bytes()
    except FileNotFoundError:
        known = f" (bundled: {', '.join(bundled)})" if bundled else ""
        raise SettingsError(f"{path}: no such {what} file{known}") from None
    except IsADirectoryError:
        raise SettingsError(f"{path}: is a folder, expected a {what} file (.toml)") from None
    except OSError as e:
        raise SettingsError(f"{path}: cannot read the {what} file ({e.strerror or e})") from None
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as e:
        raise SettingsError(
            f"{path}: not UTF-8 text (byte 0x{data[e.start]:02x} at offset {e.start}); TOML files are UTF-8"
        ) from None
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as e:
        raise SettingsError(f"{path}: not valid TOML ({e})") from None
