"""Helpers of the safety tests: one-line errors and snapshots of a folder tree."""

from __future__ import annotations

import hashlib
from pathlib import Path

import pytest


def tree(root: Path) -> dict[str, str]:
    """Every file under ``root`` (relative path) with the SHA-1 of its bytes."""
    return {p.relative_to(root).as_posix(): hashlib.sha1(p.read_bytes()).hexdigest()
            for p in sorted(root.rglob("*")) if p.is_file()}


@pytest.fixture
def snapshot():
    """The function :func:`tree`: snapshot a folder tree to compare before and after."""
    return tree


@pytest.fixture
def one_line_error(capsys):
    """Return a checker: stderr holds exactly one line ``digiteyes: error: ...``."""
    def check() -> str:
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and err[0].startswith("digiteyes: error:"), err
        return err[0]
    return check
