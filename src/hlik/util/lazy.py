"""Lazy package attributes (PEP 562): a package's public names, imported from their modules on
first use, so that importing the package (or ``hlik.cli``) does not pay for MuJoCo, SciPy or Rerun."""

from __future__ import annotations

from collections.abc import Callable, Mapping
from importlib import import_module
from importlib.util import find_spec
from typing import Any


def lazy_getattr(package: str, where: Mapping[str, str], namespace: dict[str, Any]) -> Callable[[str], Any]:
    """The module ``__getattr__`` of ``package``: name -> the attribute of that name in the module
    ``where[name]``, stored in ``namespace`` (the package's globals) once imported; any other name
    that is a submodule of ``package``, that submodule (``import hlik; hlik.util.paths`` works without
    importing ``hlik.util.paths`` first, as for any package that imports its submodules).

    Raises:
        AttributeError: a name neither in ``where`` nor a submodule.
    """

    def __getattr__(name: str) -> Any:
        if name not in where:
            if name.startswith("__") or find_spec(f"{package}.{name}") is None:
                raise AttributeError(f"module {package!r} has no attribute {name!r}")
            return import_module(f"{package}.{name}")
        value = getattr(import_module(where[name]), name)
        namespace[name] = value  # once imported, a plain attribute
        return value

    return __getattr__
