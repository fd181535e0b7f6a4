"""Filters on state sequences (thesis-free additions): the One Euro filter."""

from digiteyes.filters.one_euro import OneEuroOptions, one_euro_filter

__all__ = ["OneEuroOptions", "one_euro_filter"]
