"""Where hlik's bundled files live, in a source checkout and in an installed wheel."""

from __future__ import annotations

import os
import sys
from pathlib import Path

from hlik.util.errors import SettingsError

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib

_PACKAGE = Path(__file__).resolve().parents[1]  # hlik/, this module sits in hlik/util/
CONFIG = "hlik.toml"  # in the working folder: settings that outlive one command (``corpus = "DIR"``)


def _bundled(name: str) -> Path:
    # A wheel carries the folder inside the package; a source checkout keeps it at the root.
    inside = _PACKAGE / name
    return inside if inside.is_dir() else _PACKAGE.parents[1] / name


def robots_dir() -> Path:
    """Folder with ``<robot>.toml`` files and ``mjcf/`` models."""
    return _bundled("robots")


def tasks_dir() -> Path:
    """Folder with the bundled task-stack files."""
    return _bundled("tasks")


def demo_motion_path() -> Path:
    """The bundled demonstration motion (MMM 2.0), the default of every command."""
    return _PACKAGE / "data" / "demo_pour_wipe.xml"


def demo_bvh_path() -> Path:
    """The bundled demo's arm skeleton as BVH (:func:`hlik.human.bvh.write_bvh`), to try the BVH
    reader (needs ``pip install -e ".[bvh]"``)."""
    return _PACKAGE / "data" / "demo_pour_wipe.bvh"


def cache_dir() -> Path:
    """Where fitted and sampled pieces are cached: ``$HLIK_CACHE``, else ``$XDG_CACHE_HOME/hlik``,
    else ``~/.cache/hlik``; created if missing.

    A folder that exists but is not writable is returned: its entries can still be read, and the
    writers note what they could not cache.

    Raises:
        SettingsError: the place is a file, or the folder cannot be created (naming the variable
            it came from).
    """
    if os.environ.get("HLIK_CACHE"):
        folder, source = Path(os.environ["HLIK_CACHE"]), "HLIK_CACHE"
    elif os.environ.get("XDG_CACHE_HOME"):
        folder, source = Path(os.environ["XDG_CACHE_HOME"]) / "hlik", "XDG_CACHE_HOME"
    else:
        folder, source = Path.home() / ".cache" / "hlik", "the default cache folder"
    if folder.exists() and not folder.is_dir():
        raise SettingsError(f"{folder} ({source}): is a file, expected a folder for the cache")
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as e:
        raise SettingsError(
            f"{folder} ({source}): cannot create the cache folder ({e.strerror or e})"
        ) from None
    return folder


def corpus_setting() -> tuple[Path | None, str]:
    """The corpus folder configured for this working folder, and where the setting came from:
    ``$HLIK_CORPUS``, else ``corpus = "DIR"`` in ``./hlik.toml`` (relative to that file), else
    ``(None, "")`` (the bundled demo).

    Raises:
        SettingsError: ``hlik.toml`` unreadable or not TOML, its ``corpus`` not a string, or the
            configured folder does not exist (naming the setting).
    """
    if os.environ.get("HLIK_CORPUS"):
        folder, source = Path(os.environ["HLIK_CORPUS"]).expanduser(), "HLIK_CORPUS"
    else:
        config = Path.cwd() / CONFIG
        if not config.is_file():
            return None, ""
        try:
            table = tomllib.loads(config.read_text(encoding="utf-8"))
        except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError) as e:
            raise SettingsError(f"{CONFIG}: cannot read the settings ({' '.join(str(e).split())})") from None
        if "corpus" not in table:
            return None, ""
        if not isinstance(table["corpus"], str) or not table["corpus"]:
            raise SettingsError(f'{CONFIG}: corpus must be a folder name, e.g. corpus = "motions"')
        folder, source = config.parent / Path(table["corpus"]).expanduser(), f"corpus in {CONFIG}"
    if not folder.exists():
        raise SettingsError(f"{folder} ({source}): no such corpus folder")
    return folder, source


def default_corpus() -> Path | None:
    """The default of ``--corpus``: see :func:`corpus_setting`; ``None`` is the bundled demo."""
    return corpus_setting()[0]
