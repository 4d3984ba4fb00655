"""Atomic file output: every file hlik writes appears whole or not at all, and a set of files
(a run's ``.npz`` and ``.rrd``) appears together or not at all."""

from __future__ import annotations

import os
import secrets
import shutil
import signal
import sys
import threading
from collections.abc import Iterator
from contextlib import ExitStack, contextmanager
from pathlib import Path

if sys.platform != "win32":
    import fcntl

# Signals that end a run from outside; held back while a set of files is renamed into place.
STOP_SIGNALS = (signal.SIGINT, signal.SIGTERM)


@contextmanager
def atomic_path(path: str | Path) -> Iterator[Path]:
    """A temporary file beside ``path`` to write to; renamed onto ``path`` when the block succeeds,
    deleted when it fails or SIGINT/SIGTERM ends the program (:func:`raising_on_sigterm`). The
    result is an ordinary 0644 file (the temporary is made 0600)."""
    path = Path(path)
    tmp = _temporary(path)
    with raising_on_sigterm() as termination:
        try:
            _create(tmp)
            yield tmp
            termination.check()
            os.chmod(tmp, 0o644)
            os.replace(tmp, path)
        except BaseException as e:
            tmp.unlink(missing_ok=True)
            _name_the_target(e, {str(tmp): path})
            raise


@contextmanager
def atomic_folder(path: str | Path) -> Iterator[Path]:
    """A temporary folder beside ``path`` to write into; renamed onto ``path`` when the block
    succeeds (a folder already there is replaced, and removed only after the rename), removed when
    it fails or SIGINT/SIGTERM ends the program."""
    path = Path(path)
    tmp = _temporary(path)
    with raising_on_sigterm() as termination:
        try:
            tmp.mkdir(mode=0o755)
            yield tmp
            termination.check()
            old = _temporary(path) if path.is_dir() else None
            if old is not None:
                os.replace(path, old)
            os.replace(tmp, path)
            if old is not None:
                shutil.rmtree(old)
        except BaseException as e:
            shutil.rmtree(tmp, ignore_errors=True)
            _name_the_target(e, {str(tmp): path})
            raise


@contextmanager
def atomic_paths(*paths: str | Path) -> Iterator[tuple[Path, ...]]:
    """Temporary files beside ``paths`` to write to; all renamed onto their paths when the block
    succeeds, all deleted when it fails: the files appear together or not at all.

    While the block runs, SIGTERM raises :class:`SystemExit` (:func:`raising_on_sigterm`; SIGINT
    raises :class:`KeyboardInterrupt`) so that the temporaries are removed. The renames run under
    :func:`pair_lock` on the first path, so concurrent writers of the same paths leave the set of
    one of them, with SIGINT and SIGTERM held back until the last rename is done.

    Raises:
        OSError: a temporary cannot be created or a rename fails (the temporaries are removed).
    """
    targets = tuple(Path(p) for p in paths)
    tmps = [_temporary(path) for path in targets]
    with ExitStack() as stack:
        termination = stack.enter_context(raising_on_sigterm())
        try:
            for tmp in tmps:
                _create(tmp)
            yield tuple(tmps)
            termination.check()
            for written in tmps:
                _sync(written)  # the data is on disk before any name points at it
            # signals held first: one arriving while the lock file is made would leave it behind
            with _signals_held(), pair_lock(targets[0]):
                _replace_all(tmps, targets)
            _sync_folders(targets)
        except BaseException as e:
            _name_the_target(e, dict(zip(map(str, tmps), targets)))
            raise
        finally:
            for left in tmps:  # a renamed temporary is gone already
                left.unlink(missing_ok=True)


def _name_the_target(error: BaseException, targets: dict[str, Path]) -> None:
    """An OSError about a temporary names the file it stands for: users never see the temporary."""
    if isinstance(error, OSError):
        for attr in ("filename", "filename2"):
            name = getattr(error, attr)
            if name is not None and str(name) in targets:
                setattr(error, attr, str(targets[str(name)]))
        if error.filename is None:  # a failed write (a full disk) names no file: name the targets
            error.filename = ", ".join(str(t) for t in targets.values())


def _temporary(path: Path) -> Path:
    """A new hidden name beside ``path``, chosen before the file is made: whenever an interrupt
    comes, the cleanup knows what to remove (``mkstemp`` returns the name only once it made the file)."""
    return path.with_name(f".{path.name}.{secrets.token_hex(6)}.tmp")


def _create(tmp: Path) -> None:
    os.close(os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600))


def _replace_all(tmps: list[Path], targets: tuple[Path, ...]) -> None:
    done: list[Path] = []
    try:
        for tmp, path in zip(tmps, targets):
            os.replace(tmp, path)
            done.append(path)
    except BaseException:
        for path in done:  # a rename failed (practically never, in the same folder): none of the set
            path.unlink(missing_ok=True)
        raise


def _sync(path: Path) -> None:
    os.chmod(path, 0o644)  # an ordinary file (the temporary is made 0600)
    fd = os.open(path, os.O_RDONLY)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


def _sync_folders(paths: tuple[Path, ...]) -> None:
    """Make the renames durable; best effort (not every filesystem syncs a folder)."""
    if sys.platform == "win32":  # pragma: no cover
        return
    for folder in {p.parent for p in paths}:
        try:
            fd = os.open(folder, os.O_RDONLY)
        except OSError:
            continue
        try:
            os.fsync(fd)
        except OSError:
            pass
        finally:
            os.close(fd)


@contextmanager
def pair_lock(path: str | Path) -> Iterator[None]:
    """Hold the exclusive lock :func:`atomic_paths` takes to rename onto ``path`` (its first path):
    ``flock`` on ``.<name>.lock`` beside it, created, and removed when released."""
    if sys.platform == "win32":  # pragma: no cover
        yield
        return
    lock = Path(path).with_name(f".{Path(path).name}.lock")
    while True:
        fd = os.open(lock, os.O_RDWR | os.O_CREAT, 0o644)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX)
            held = os.fstat(fd)
            try:
                now = os.stat(lock)
            except FileNotFoundError:
                now = None
        except BaseException:
            os.close(fd)
            raise
        # the holder before us removes the file it locked: lock the one that is there now
        if now is not None and (now.st_dev, now.st_ino) == (held.st_dev, held.st_ino):
            break
        os.close(fd)
    try:
        yield
    finally:
        lock.unlink(missing_ok=True)  # while still held, so no one waits on a removed file
        os.close(fd)


class Termination:
    """A SIGTERM handler that raises :class:`SystemExit` (status 128 + 15) and remembers the signal,
    so that :meth:`check` can end the program after all when the exception was swallowed (Python
    ignores exceptions raised in ``__del__``, where a handler may happen to run)."""

    def __init__(self) -> None:
        self.signum = 0

    def __call__(self, signum: int, _frame: object) -> None:
        self.signum = signum
        raise SystemExit(128 + signum)

    def check(self) -> None:
        """Raise :class:`SystemExit` if a SIGTERM came."""
        if self.signum:
            raise SystemExit(128 + self.signum)


@contextmanager
def raising_on_sigterm() -> Iterator[Termination]:
    """In the block, SIGTERM raises :class:`SystemExit` where it would kill the process outright,
    so that ``finally`` blocks and the temporaries' cleanup run; yields the :class:`Termination`
    handler (check it before a step that must not follow a termination). A handler the program set
    is kept; signal handlers belong to the main thread, so elsewhere this sets none."""
    current = (
        signal.getsignal(signal.SIGTERM) if threading.current_thread() is threading.main_thread() else None
    )
    if isinstance(current, Termination):  # nested: the outer block's handler
        yield current
        return
    handler = Termination()
    if current is not signal.SIG_DFL:
        yield handler  # never called
        return
    signal.signal(signal.SIGTERM, handler)
    hook = sys.unraisablehook

    def quiet(unraisable: sys.UnraisableHookArgs) -> None:
        # the handler's exit raised where Python ignores exceptions (a weakref callback, __del__):
        # no traceback for it, check() ends the program
        if not (handler.signum and unraisable.exc_type is SystemExit):
            hook(unraisable)

    sys.unraisablehook = quiet
    try:
        yield handler
        handler.check()
    finally:
        if sys.unraisablehook is quiet:
            sys.unraisablehook = hook
        if signal.getsignal(signal.SIGTERM) is handler:  # unless the block set another
            signal.signal(signal.SIGTERM, signal.SIG_DFL)


@contextmanager
def _signals_held() -> Iterator[None]:
    """SIGINT and SIGTERM that arrive in the block are delivered when it ends.

    Python runs signal handlers in the main thread between bytecodes, so a handler that only
    notes the signal holds it back even when the operating system hands it to another thread.
    """
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    pending: list[int] = []
    previous = {s: signal.signal(s, lambda signum, _frame: pending.append(signum)) for s in STOP_SIGNALS}
    try:
        yield
    finally:
        for s, handler in previous.items():
            signal.signal(s, handler)
        for signum in dict.fromkeys(pending):
            signal.raise_signal(signum)
