"""hlik's version, where any stage can read it without importing the package's names."""

__version__ = "0.1.0"
