"""Reading hlik's TOML inputs (stacks, metrics, approach files, robots) with one-line errors."""

from __future__ import annotations

import difflib
import sys
from collections.abc import Iterable, Mapping, Sequence
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
    except RecursionError:  # tomllib recurses per nesting level
        raise SettingsError(f"{path}: not valid TOML (arrays or tables nested too deeply)") from None


def unknown_key(
    table: Mapping, allowed: Iterable[str], where: str, renamed: Mapping[str, str] | None = None
) -> str | None:
    """None if every key of ``table`` is ``allowed``; else the problem with the first unknown one,
    e.g. ``"unknown key 'placment' in the top-level table (did you mean 'placement'?); choose
    from: ..."`` (``where`` names the table), or the key's new name where ``renamed`` (old -> new) knows it.
    Every TOML reader refuses such a key with its file, since a misspelt key would otherwise leave
    its default silently in place.
    """
    allowed = sorted(allowed)
    unknown = sorted(set(table) - set(allowed), key=str)
    if not unknown:
        return None
    key = unknown[0]
    hint = (
        f" (now {renamed[key]!r})" if renamed and renamed.get(key) in allowed else did_you_mean(key, allowed)
    )
    return f"unknown key {key!r} in {where}{hint}; choose from: {', '.join(allowed)}"


def did_you_mean(name: object, choices: Iterable[str]) -> str:
    """``" (did you mean 'x'?)"`` with the choice closest to ``name``, or ``""`` if none is close."""
    close = difflib.get_close_matches(str(name), list(choices), n=1, cutoff=0.5)  # 'xo' for 'x0': 0.5
    return f" (did you mean {close[0]!r}?)" if close else ""
