"""Trackers by name: every tracker registers a factory and its options type once, and the
run loop, ``digiteyes track --tracker NAME`` and the benchmarks create it by name.

A tracker module registers itself at the end of its package's ``__init__`` (the shipped
ones in :mod:`digiteyes.trackers`); code outside the package (a test, a plug-in) calls
:func:`register_tracker` before :func:`create_tracker`. docs/architecture.md has a worked
example.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from digiteyes.camera import Rig
from digiteyes.errors import DigitEyesError
from digiteyes.kinematics import KinematicModel
from digiteyes.trackers.base import Tracker

TrackerFactory = Callable[[KinematicModel, Rig, Any], Tracker]
"""``factory(model, rig, options) -> Tracker``; ``options`` is an ``options_type``."""


class TrackerError(DigitEyesError, ValueError):
    """An unknown tracker name or options the tracker does not have."""


@dataclass(frozen=True)
class TrackerEntry:
    """One registered tracker: its name, factory, options dataclass and one-line help."""

    name: str
    factory: TrackerFactory
    options_type: type
    help: str


_REGISTRY: dict[str, TrackerEntry] = {}


def register_tracker(name: str, factory: TrackerFactory, options_type: type,
                     help: str) -> TrackerEntry:
    """Make a tracker creatable by ``name``.

    Parameters
    ----------
    name : the name users type (``digiteyes track --tracker NAME``); lower case, no spaces.
    factory : ``factory(model, rig, options)`` returns a fresh tracker.
    options_type : a dataclass whose fields are the tracker's settings (all with defaults);
        :func:`create_tracker` builds it from keyword arguments.
    help : one line for ``--help``.

    Registering a name again replaces the entry (a module imported twice stays harmless).
    """
    if not name or name != name.strip().lower() or " " in name:
        raise TrackerError(f"tracker names are lower case without spaces, got {name!r}")
    if not dataclasses.is_dataclass(options_type):
        raise TrackerError(f"options_type of tracker {name!r} must be a dataclass, got "
                           f"{options_type!r}")
    entry = TrackerEntry(name, factory, options_type, help)
    _REGISTRY[name] = entry
    return entry


def tracker_names() -> tuple[str, ...]:
    """The registered tracker names, in registration order."""
    return tuple(_REGISTRY)


def tracker_entry(name: str) -> TrackerEntry:
    """The registry entry of ``name``; :class:`TrackerError` listing the names otherwise."""
    try:
        return _REGISTRY[name]
    except KeyError:
        raise TrackerError(f"no tracker named {name!r}; choose from "
                           f"{', '.join(tracker_names())}") from None


def create_tracker(name: str, model: KinematicModel, rig: Rig, **options: Any) -> Tracker:
    """A new tracker ``name`` for ``model`` and ``rig``, with ``options`` as fields of its
    options type (unset fields keep their defaults). A dotted key sets a field of a nested
    settings object (``digit_search.passes=0``, ``templates.window_px=2``), the rest of
    which keeps its defaults.

    Raises :class:`TrackerError` for an unknown name or option, naming the choices.
    """
    entry = tracker_entry(name)
    nested: dict[str, Any] = {}
    for key, value in options.items():
        node = nested
        *path, last = key.split(".")
        for part in path:
            node = node.setdefault(part, _Nested())
            if not isinstance(node, _Nested):
                raise TrackerError(f"tracker {name!r}: option {part!r} is set and has "
                                   f"parts set too")
        if isinstance(node.get(last), _Nested):
            raise TrackerError(f"tracker {name!r}: option {key!r} is set and has parts set "
                               f"too")
        node[last] = value
    try:
        settings = _settings(entry.options_type, None, nested, name, "")
    except TrackerError:
        raise
    except (TypeError, ValueError) as exc:
        raise TrackerError(f"tracker {name!r}: {exc}") from None
    return entry.factory(model, rig, settings)


class _Nested(dict):
    """Options under a dotted key's prefix (a nested settings object's fields)."""


def _settings(options_type: type, base: Any, options: dict[str, Any], name: str,
              prefix: str) -> Any:
    """``base`` (or a new ``options_type``) with ``options`` set, nested ones applied to
    the settings object their prefix names."""
    fields = {f.name: f for f in dataclasses.fields(options_type)}
    unknown = sorted(set(options) - set(fields))
    if unknown:
        where = f"{prefix[:-1]}'s options" if prefix else "its options"
        raise TrackerError(f"tracker {name!r} has no option "
                           f"{', '.join(repr(prefix + u) for u in unknown)}; {where} are "
                           f"{', '.join(sorted(fields)) or 'none'}")
    values = {}
    for key, value in options.items():
        if isinstance(value, _Nested):
            current = getattr(base, key) if base is not None else _default(fields[key])
            if not dataclasses.is_dataclass(current):
                raise TrackerError(f"tracker {name!r}: option {prefix + key!r} has no "
                                   f"parts to set")
            value = _settings(type(current), current, value, name, f"{prefix}{key}.")
        else:
            _check_plain_type(fields[key], value, name, prefix + key)
        values[key] = value
    return dataclasses.replace(base, **values) if base is not None else options_type(**values)


_PLAIN_TYPES = {"bool": (bool,), "int": (int,), "float": (int, float), "str": (str,)}
"""Option annotations whose values are checked here (anything else is the options
class's own business): the Python types each accepts (a bool is no number)."""


def _check_plain_type(field: dataclasses.Field, value: Any, name: str, key: str) -> None:
    """Raise :class:`TrackerError` when an option annotated ``bool``, ``int``, ``float`` or
    ``str`` (optionally ``| None``) gets a value of another type: ``--option
    silhouette_check=maybe`` arrives as the string ``"maybe"``, which a bool field would
    otherwise keep and read as true."""
    annotation = field.type if isinstance(field.type, str) else getattr(
        field.type, "__name__", "")
    kinds = [part.strip() for part in annotation.split("|")]
    optional = "None" in kinds
    kinds = [k for k in kinds if k != "None"]
    if len(kinds) != 1 or kinds[0] not in _PLAIN_TYPES or (value is None and optional):
        return
    allowed = _PLAIN_TYPES[kinds[0]]
    if isinstance(value, bool) != (kinds[0] == "bool") or not isinstance(value, allowed):
        wanted = {"bool": "true or false", "int": "an integer", "float": "a number",
                  "str": "a string"}[kinds[0]]
        raise TrackerError(f"tracker {name!r}: {key} must be {wanted}"
                           f"{' or null' if optional else ''}, got {value!r}")


def _default(field: dataclasses.Field) -> Any:
    if field.default is not dataclasses.MISSING:
        return field.default
    if field.default_factory is not dataclasses.MISSING:
        return field.default_factory()
    return None
