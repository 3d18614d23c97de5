"""Errors that reach the analyst as one clear line, never a traceback.

Every problem with input names its place: a file with line and column, or a
configuration key. The command-line and TUI layers catch :class:`GcsError` and print
``str(err)``; anything else escaping is a bug in GCS.
"""

from __future__ import annotations

import os
from dataclasses import dataclass


class GcsError(Exception):
    """Base of every error GCS reports to the user."""


@dataclass
class InputError(GcsError):
    """Bad input, located as precisely as we can.

    Attributes
    ----------
    message : what is wrong, in plain words.
    file : the file at fault, if any.
    line, column : 1-based position in a text file (column may be a name).
    key : the dotted configuration key at fault, e.g. ``sensor[2].noise``.
    """

    message: str
    file: str | os.PathLike | None = None
    line: int | None = None
    column: int | str | None = None
    key: str | None = None

    def __post_init__(self) -> None:
        super().__init__(str(self))

    def __str__(self) -> str:  # one line, most specific place first
        where = []
        if self.file is not None:
            place = str(self.file)
            if self.line is not None:
                place += f":{self.line}"
                if isinstance(self.column, int):
                    place += f":{self.column}"
            where.append(place)
        if isinstance(self.column, str):
            where.append(f"column '{self.column}'")
        if self.key is not None:
            where.append(f"key '{self.key}'")
        prefix = ", ".join(where)
        return f"{prefix}: {self.message}" if prefix else self.message

    def __reduce__(self):  # keep picklable for worker processes
        return (type(self), (self.message, self.file, self.line, self.column, self.key))


class ConfigError(InputError):
    """A problem in the analysis configuration (TOML)."""


class DataFileError(InputError):
    """An HDF5 data set (SDF, SCDS, ASF) that is missing, truncated, corrupt or locked."""


class EstimationError(GcsError):
    """The estimator cannot proceed (divergence, no data); the message says why."""


class UnobservableError(EstimationError):
    """The normal matrix is singular; ``combinations`` names what cannot be separated."""

    def __init__(self, message: str, combinations: list[str]):
        super().__init__(message)
        self.combinations = combinations
