"""``python -m hlik.cli``: the command line, as ``hlik``."""

from hlik.cli import main

main()
