"""The criteria hlik knows, by the paper's names: the only list metrics, solvers, stacks, the CLI
and the recording read.

Adding a criterion is one module (a :class:`~hlik.criteria.base.Criterion` subclass with its name,
Table II/III constants, residual, Jacobian and cost) and one :func:`register` call, here or in user
code.
"""

from __future__ import annotations

from collections.abc import Iterable

from hlik.criteria.base import Criterion
from hlik.criteria.eea import EEA, EEA_r
from hlik.criteria.functional import fORI, fORI_off, fPOS, fPOS_off
from hlik.criteria.joints import HJL, HJA_r, fJLA
from hlik.criteria.manipulability import MAN_r
from hlik.criteria.smoothness import MJE
from hlik.criteria.soechting import SOA_q, SOA_x
from hlik.criteria.synergy import MIS, SYN, SYN_r
from hlik.util.errors import SettingsError, UnknownNameError

_CRITERIA: dict[str, type[Criterion]] = {}


def register(cls: type[Criterion]) -> type[Criterion]:
    """Add a criterion class under ``cls.name`` (usable as a class decorator); returns ``cls``.

    Raises:
        ValueError: the name is taken by another class.
    """
    known = _CRITERIA.get(cls.name)
    if known is not None and known is not cls:
        raise SettingsError(f"a criterion named {cls.name!r} is registered already ({known.__qualname__})")
    _CRITERIA[cls.name] = cls
    return cls


def unregister(name: str) -> None:
    """Remove the criterion called ``name`` (no error if absent)."""
    _CRITERIA.pop(name, None)


def human_likeness() -> tuple[str, ...]:
    """Names of the human-likeness criteria, in registration order (the paper's first)."""
    return tuple(n for n, c in _CRITERIA.items() if not c.functional)


def functional() -> tuple[str, ...]:
    """Names of the functional criteria (fJLA, fPOS, fORI, fPOS_off, fORI_off)."""
    return tuple(n for n, c in _CRITERIA.items() if c.functional)


def criterion_class(name: str) -> type[Criterion]:
    """The class registered as ``name``.

    Raises:
        KeyError: with the known human-likeness criteria in the message.
    """
    try:
        return _CRITERIA[name]
    except KeyError:
        known = ", ".join(human_likeness())
        raise UnknownNameError(f"unknown criterion {name!r}; choose from: {known}") from None


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


for _cls in (
    EEA,
    SOA_x,
    SOA_q,
    HJL,
    SYN,
    MIS,
    MJE,
    HJA_r,
    SYN_r,
    EEA_r,
    MAN_r,
    fJLA,
    fPOS,
    fORI,
    fPOS_off,
    fORI_off,
):
    register(_cls)
