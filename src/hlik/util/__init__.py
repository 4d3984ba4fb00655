"""The utilities below every stage: ``errors`` (every error an ``HlikError``), ``paths`` (bundled
files, the cache folder, the demo take), ``atomic`` (files that appear whole), ``cache`` (disk-cache
entries carrying their key and a checksum), ``tomlfile`` (TOML with file-named errors), ``spatial``
(rotations, frames, forward kinematics), ``lazy`` (package names imported on first use),
``version``."""

from __future__ import annotations

from hlik.util.lazy import lazy_getattr

__getattr__ = lazy_getattr(__name__, {}, globals())
