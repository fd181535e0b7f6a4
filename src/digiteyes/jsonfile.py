"""Reading JSON files that must hold an object, shared by the readers of states, rigs and
datasets (a base module: it imports only :mod:`digiteyes.errors`)."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from digiteyes.errors import DigitEyesError


def read_json_object(path: str | Path, error: type[DigitEyesError], what: str,
                     expected: str = "a JSON object") -> dict[str, Any]:
    """Read a JSON file that must hold an object; any failure raises ``error`` naming the
    file, what it should have been (``what``, e.g. "rig file") and what it should hold."""
    path = Path(path)
    try:
        payload = json.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise error(f"{path}: no such {what}") from None
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise error(f"{path}: not a readable JSON {what} ({exc})") from None
    if not isinstance(payload, dict):
        raise error(f"{path}: expected {expected}")
    return payload
