"""The criteria hlik knows, by the paper's names: the only list metrics, solvers, stacks, the CLI
and the recording read.

Adding a criterion is one module (a :class:`~hlik.criteria.base.Criterion` subclass with its name,
Table II/III constants, residual, Jacobian and cost) and one line in ``_BUILTIN`` here, or one
:func:`register` call in user code.
"""

from __future__ import annotations

from collections.abc import Iterable
from importlib import import_module
from typing import TYPE_CHECKING

from hlik.util.errors import SettingsError, UnknownNameError

if TYPE_CHECKING:
    from hlik.criteria.base import Criterion

# The built-in criteria, the paper's first: name -> (module, functional). A module is imported
# when its criterion is first used, so that a name is checked (the CLI does, before anything
# runs) without loading SciPy and MuJoCo; the class is the module's attribute of that name.
_BUILTIN: dict[str, tuple[str, bool]] = {
    "EEA": ("eea", False),
    "SOA_x": ("soechting", False),
    "SOA_q": ("soechting", False),
    "HJL": ("joints", False),
    "SYN": ("synergy", False),
    "MIS": ("synergy", False),
    "MJE": ("smoothness", False),
    "HJA_r": ("joints", False),
    "SYN_r": ("synergy", False),
    "EEA_r": ("eea", False),
    "MAN_r": ("manipulability", False),
    "fJLA": ("joints", True),
    "fPOS": ("functional", True),
    "fORI": ("functional", True),
    "fPOS_off": ("functional", True),
    "fORI_off": ("functional", True),
}
_FUNCTIONAL: dict[str, bool] = {n: f for n, (_, f) in _BUILTIN.items()}  # every name, in order
_CRITERIA: dict[str, type[Criterion]] = {}  # the classes imported or registered so far


def register(cls: type[Criterion]) -> type[Criterion]:
    """Add a criterion class under ``cls.name`` (usable as a class decorator); returns ``cls``.

    Raises:
        SettingsError: the name is taken by another class (a ``ValueError``).
    """
    known = criterion_class(cls.name) if cls.name in _FUNCTIONAL else None
    if known is not None and known is not cls:
        raise SettingsError(f"a criterion named {cls.name!r} is registered already ({known.__qualname__})")
    _CRITERIA[cls.name] = cls
    _FUNCTIONAL[cls.name] = cls.functional
    return cls


def unregister(name: str) -> None:
    """Remove the criterion called ``name`` (no error if absent)."""
    _CRITERIA.pop(name, None)
    _FUNCTIONAL.pop(name, None)


def human_likeness() -> tuple[str, ...]:
    """Names of the human-likeness criteria, in registration order (the paper's first)."""
    return tuple(n for n, f in _FUNCTIONAL.items() if not f)


def functional() -> tuple[str, ...]:
    """Names of the functional criteria (fJLA, fPOS, fORI, fPOS_off, fORI_off)."""
    return tuple(n for n, f in _FUNCTIONAL.items() if f)


def criterion_class(name: str) -> type[Criterion]:
    """The class registered as ``name``.

    Raises:
        UnknownNameError: with the known human-likeness criteria in the message.
    """
    if name not in _FUNCTIONAL:
        raise UnknownNameError(f"unknown criterion {name!r}; choose from: {', '.join(human_likeness())}")
    if name not in _CRITERIA:
        module, _ = _BUILTIN[name]
        _CRITERIA[name] = _named(import_module(f"hlik.criteria.{module}"), name)
    return _CRITERIA[name]


def _named(module, name: str) -> type[Criterion]:
    """The class in ``module`` whose ``name`` is ``name`` (the class of that name first).

    Raises:
        SettingsError: the module has none, naming the module and what it has.
    """
    classes = [c for c in vars(module).values() if isinstance(c, type) and getattr(c, "name", None) == name]
    own = getattr(module, name, None)
    if isinstance(own, type) and own in classes:
        return own
    if classes:
        return classes[0]
    raise SettingsError(
        f"criterion {name!r}: module {module.__name__} has no class with name = {name!r} "
        "(registry._BUILTIN names its module)"
    )


def criterion(name: str, robot: object, learned: object | None = None) -> Criterion:
    """A new instance of criterion ``name`` for ``robot``, built from its piece of ``learned``
    (:class:`~hlik.criteria.learned.Learned`; :attr:`Criterion.learned` names it).

    Raises:
        SettingsError: the criterion learns from human motion and ``learned`` is None.
    """
    make: type[Criterion] = criterion_class(name)
    if make.learned is None:
        return make(robot)
    if learned is None:
        raise SettingsError(
            f"criterion {name} is built from learned {make.learned} (hlik.criteria.learned.learn); "
            "none were given"
        )
    return make(robot, getattr(learned, make.learned))


def learns(names: Iterable[str]) -> bool:
    """True if any of the criteria ``names`` is built from a learned piece."""
    return any(criterion_class(n).learned is not None for n in names)
