"""The bounds every solver setting is checked against, by the settings classes and the stack
files alike (imports nothing, so the command line checks a stack before the heavy libraries load)."""

MAX_WEIGHT = 1e6  # any solver weight or gamma; the bundled stacks' largest is 30 (1e300 overflowed)
MAX_COUNT = 100_000  # iterations or evaluations per frame; the defaults are 20-150
