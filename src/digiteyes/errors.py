"""Errors raised by digiteyes. Each says what was wrong and, for files, where."""

from __future__ import annotations


class DigitEyesError(Exception):
    """Base class: the CLI prints these as one line, never as a traceback."""


class ModelFileError(DigitEyesError):
    """A model file could not be parsed; names the file, the line and what was expected."""

    def __init__(self, path: str, line: int | None, message: str) -> None:
        self.path = path
        self.line = line
        self.message = message
        where = f"{path}:{line}" if line is not None else path
        super().__init__(f"{where}: {message}")


class StateError(DigitEyesError, ValueError):
    """A state vector or state file does not fit its model."""


class CameraError(DigitEyesError, ValueError):
    """A camera or rig description is invalid."""


class DatasetError(DigitEyesError):
    """A dataset folder on disk is missing parts or its parts disagree."""
