"""Where hlik's bundled files live, in a source checkout and in an installed wheel."""

from __future__ import annotations

import os
from pathlib import Path

_PACKAGE = Path(__file__).resolve().parent


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


def cache_dir() -> Path:
    """Where fitted and sampled pieces are cached: ``$HLIK_CACHE``, else ``$XDG_CACHE_HOME/hlik``,
    else ``~/.cache/hlik``."""
    if "HLIK_CACHE" in os.environ:
        return Path(os.environ["HLIK_CACHE"])
    return Path(os.environ.get("XDG_CACHE_HOME", Path.home() / ".cache")) / "hlik"
