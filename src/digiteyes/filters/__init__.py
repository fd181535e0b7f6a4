"""Filters on state sequences (thesis-free additions): the One Euro filter."""

from digiteyes.filters.one_euro import (
    OneEuroFilter,
    OneEuroOptions,
    OneEuroTrace,
    one_euro_filter,
    one_euro_trace,
    restarts_after_losses,
)

__all__ = ["OneEuroFilter", "OneEuroOptions", "OneEuroTrace", "one_euro_filter", "one_euro_trace",
           "restarts_after_losses"]
