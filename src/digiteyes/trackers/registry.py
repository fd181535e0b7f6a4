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
    options type (unset fields keep their defaults).

    Raises :class:`TrackerError` for an unknown name or option, naming the choices.
    """
    entry = tracker_entry(name)
    fields = {f.name for f in dataclasses.fields(entry.options_type)}
    unknown = sorted(set(options) - fields)
    if unknown:
        raise TrackerError(f"tracker {name!r} has no option {', '.join(map(repr, unknown))}; "
                           f"its options are {', '.join(sorted(fields)) or 'none'}")
    try:
        settings = entry.options_type(**options)
    except (TypeError, ValueError) as exc:
        raise TrackerError(f"tracker {name!r}: {exc}") from None
    return entry.factory(model, rig, settings)
