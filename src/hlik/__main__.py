"""``python -m hlik``: the command line, as ``hlik``."""

from hlik.cli import main

main()
