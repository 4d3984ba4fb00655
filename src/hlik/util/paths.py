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
DEMO = "demo"  # HLIK_CORPUS / --corpus value naming the bundled demo


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


def user_config() -> Path:
    """The user's settings file: ``$XDG_CONFIG_HOME/hlik/config.toml`` (``~/.config/hlik/...``),
    where ``hlik learn --corpus DIR`` remembers the corpus."""
    base = os.environ.get("XDG_CONFIG_HOME") or str(Path.home() / ".config")
    return Path(base).expanduser() / "hlik" / "config.toml"


def shared_takes() -> Path | None:
    """The folder of KIT bimanual takes beside a checkout, if there: ``$HLIK_DATA/kit_bimanual``
    where ``HLIK_DATA`` is set (and nothing else: a mistyped one is not replaced by another
    folder), else ``../shared/motion_data/kit_bimanual`` from the working folder, else from the
    source checkout hlik is installed from (``pip install -e``), so that a command run in another
    folder finds the same takes (the default of ``hlik study`` and, holding takes, of the corpus)."""
    data = os.environ.get("HLIK_DATA")
    if data:
        folder = Path(data) / "kit_bimanual"
        return folder if folder.is_dir() else None
    checkout = _PACKAGE.parents[1]  # src/hlik -> the checkout's root, in an editable install
    roots = [Path.cwd()] + ([checkout] if (checkout / "pyproject.toml").is_file() else [])
    for root in roots:
        folder = root.parent / "shared" / "motion_data" / "kit_bimanual"
        if folder.is_dir():
            return folder
    return None


def no_shared_takes() -> str:
    """Why :func:`shared_takes` found none, for a summary line: where ``HLIK_DATA`` is set, that
    it holds no takes (a mistyped one is named, not replaced)."""
    data = os.environ.get("HLIK_DATA")
    if data:
        return f"no corpus of recorded motion found: HLIK_DATA={data} holds no kit_bimanual takes"
    return "no corpus of recorded motion found"


def shared_corpus() -> Path | None:
    """:func:`shared_takes` where it holds MMM takes (``*.xml``)."""
    folder = shared_takes()
    return folder if folder is not None and any(folder.glob("*.xml")) else None


def corpus_setting() -> tuple[Path | None, str]:
    """The corpus folder the criteria are learned from when a command is given none, and where
    the setting came from, first found of:

    1. ``$HLIK_CORPUS`` (``demo``: the bundled demo);
    2. ``corpus = "DIR"`` in ``./hlik.toml`` (relative to that file);
    3. ``corpus = "DIR"`` in :func:`user_config` (written by ``hlik learn --corpus DIR``);
    4. the shared KIT takes (:func:`shared_corpus`);
    5. ``(None, "")``: the bundled demo, synthetic (the commands warn).

    Raises:
        SettingsError: a settings file unreadable or not TOML, its ``corpus`` not a string, or the
            configured folder does not exist (naming the setting).
    """
    if os.environ.get("HLIK_CORPUS"):
        if os.environ["HLIK_CORPUS"] == DEMO:
            return None, "HLIK_CORPUS"
        folder, source = Path(os.environ["HLIK_CORPUS"]).expanduser(), "HLIK_CORPUS"
    else:
        found = _configured(Path.cwd() / CONFIG, CONFIG) or _configured(user_config(), str(user_config()))
        if found is None:
            shared = shared_corpus()
            return (shared, "the shared KIT takes") if shared is not None else (None, "")
        folder, source = found
    if not folder.exists():
        raise SettingsError(f"{folder} ({source}): no such corpus folder")
    return folder, source


def _configured(config: Path, name: str) -> tuple[Path, str] | None:
    """``corpus`` of a settings file and the setting's name, None where there is none."""
    if not config.is_file():
        return None
    try:
        table = tomllib.loads(config.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError) as e:
        raise SettingsError(f"{name}: cannot read the settings ({' '.join(str(e).split())})") from None
    if "corpus" not in table:
        return None
    if not isinstance(table["corpus"], str) or not table["corpus"]:
        raise SettingsError(f'{name}: corpus must be a folder name, e.g. corpus = "motions"')
    return config.parent / Path(table["corpus"]).expanduser(), f"corpus in {name}"


def remember_corpus(folder: Path) -> Path:
    """Write ``corpus = "FOLDER"`` (absolute) into :func:`user_config`, keeping its other lines;
    returns the file."""
    config = user_config()
    lines = config.read_text(encoding="utf-8").splitlines() if config.is_file() else []
    lines = [line for line in lines if not line.strip().startswith("corpus")]
    value = str(folder.resolve()).replace("\\", "\\\\").replace('"', '\\"')
    config.parent.mkdir(parents=True, exist_ok=True)
    config.write_text("\n".join([f'corpus = "{value}"', *lines]) + "\n", encoding="utf-8")
    return config
