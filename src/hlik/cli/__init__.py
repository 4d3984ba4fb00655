"""The ``hlik`` command line: a thin script over the library (:mod:`hlik.pipeline` for ``run``), one
module per command. Bad input ends in one line on stderr and exit code 2."""

from __future__ import annotations

from hlik.cli import evaluate, export, learn, replay, robots, run, study
from hlik.cli.app import app
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


def main() -> None:  # pragma: no cover
    app()


__all__ = ["app", "main", "write_outputs"]
