"""The ``hlik`` command line: a thin script over the library (:mod:`hlik.pipeline` for ``run``), one
module per command. Bad input ends in one line on stderr and exit code 2."""

from __future__ import annotations

import os
import signal
import sys
import threading

from hlik.cli import evaluate, export, learn, replay, robots, run, study
from hlik.cli.app import INTERRUPTED, TERMINATED, app
from hlik.cli.outputs import write_outputs

# in the order ``hlik --help`` lists them
for command in (
    run.run,
    evaluate.evaluate,
    export.export,
    replay.replay,
    learn.learn,
    study.study,
    robots.robots,
    robots.info,
    robots.calibrate,
):
    app.command()(command)


def main() -> None:
    """The ``hlik`` command: :data:`app`, ended at once where it ends by Ctrl-C (exit 130) or
    SIGTERM (143), before the interpreter's shutdown, so that a command that has said how it
    stopped exits with that code: in CI a study that had printed "interrupted: ... cells kept"
    died by SIGINT instead (exit -2), twice in some hundred runs, with SIGINT already ignored
    (how was not found). A Ctrl-C that escapes a command's own handling ends with 130 too."""
    try:
        app()
    except SystemExit as stop:
        if stop.code in (INTERRUPTED, TERMINATED):
            _exit_now(int(stop.code))
        raise
    except KeyboardInterrupt:
        _exit_now(INTERRUPTED)


def _exit_now(code: int) -> None:
    """Exit with ``code`` now: the streams flushed, no later signal heeded, no shutdown."""
    if threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGINT, signal.SIG_IGN)
    for stream in (sys.stdout, sys.stderr):
        stream.flush()
    os._exit(code)


__all__ = ["app", "main", "write_outputs"]
