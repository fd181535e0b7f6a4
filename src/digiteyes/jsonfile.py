"""Reading JSON files that must hold an object, shared by the readers of states, rigs and
datasets (a base module: it imports only :mod:`digiteyes.errors`).

:func:`load_json_text` is the one JSON loader of every user file: it bounds the file size,
the nesting depth and the length of integers, so no input can raise anything but the
caller's own :class:`~digiteyes.errors.DigitEyesError`.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from digiteyes.errors import DigitEyesError

MAX_JSON_BYTES = 64 * 1024 * 1024
"""Largest JSON file read (bytes): states, rigs and sequence descriptions are kilobytes."""
MAX_JSON_DEPTH = 64
"""Deepest nesting of arrays and objects accepted (a rig needs 4)."""
MAX_INT_DIGITS = 40
"""Longest integer literal accepted (digits); larger numbers are written with an exponent."""


def _parse_int(text: str) -> int:
    if len(text.lstrip("-")) > MAX_INT_DIGITS:
        raise ValueError(f"integer with {len(text)} digits (at most {MAX_INT_DIGITS})")
    return int(text)


def _depth(text: str) -> int:
    """Deepest nesting of ``[``/``{`` outside strings (a linear scan, no recursion)."""
    depth = deepest = 0
    in_string = escaped = False
    for char in text:
        if in_string:
            if escaped:
                escaped = False
            elif char == "\\":
                escaped = True
            elif char == '"':
                in_string = False
        elif char == '"':
            in_string = True
        elif char in "[{":
            depth += 1
            deepest = max(deepest, depth)
        elif char in "]}":
            depth -= 1
    return deepest


def load_json_text(text: str, where: str, error: type[DigitEyesError], what: str) -> Any:
    """Parse JSON ``text`` read from ``where``; any failure raises ``error`` naming it."""
    if len(text) > MAX_JSON_BYTES:
        raise error(f"{where}: {what} is larger than {MAX_JSON_BYTES // 2**20} MB")
    if text.count("[") + text.count("{") > MAX_JSON_DEPTH and _depth(text) > MAX_JSON_DEPTH:
        raise error(f"{where}: {what} nests deeper than {MAX_JSON_DEPTH} levels")
    try:
        return json.loads(text, parse_int=_parse_int)
    except json.JSONDecodeError as exc:
        raise error(f"{where}: not a readable JSON {what} ({exc})") from None
    except (ValueError, OverflowError, RecursionError) as exc:
        raise error(f"{where}: not a readable JSON {what} ({exc})") from None


def read_json_object(path: str | Path, error: type[DigitEyesError], what: str,
                     expected: str = "a JSON object") -> dict[str, Any]:
    """Read a JSON file that must hold an object; any failure raises ``error`` naming the
    file, what it should have been (``what``, e.g. "rig file") and what it should hold."""
    path = Path(path)
    try:
        if path.is_file() and path.stat().st_size > MAX_JSON_BYTES:
            raise error(f"{path}: {what} is larger than {MAX_JSON_BYTES // 2**20} MB")
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise error(f"{path}: no such {what}") from None
    except (OSError, UnicodeDecodeError, ValueError) as exc:
        raise error(f"{path}: not a readable JSON {what} ({exc})") from None
    payload = load_json_text(text, str(path), error, what)
    if not isinstance(payload, dict):
        raise error(f"{path}: expected {expected}")
    return payload
