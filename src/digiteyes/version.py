"""The version of digiteyes (a base module: importable from every layer)."""

__version__ = "0.1.0"
