"""
Argparse value types that validate at the edge.

Every option is checked once, here, with a message naming the option's value (argparse adds the
option's name), before any work starts.
"""
from __future__ import annotations

import argparse
import math


def _number(kind, s: str, what: str):
    try:
        v = kind(s)
    except (TypeError, ValueError):
        raise argparse.ArgumentTypeError(f'{s!r} is not {what}') from None
    if kind is float and not math.isfinite(v):
        raise argparse.ArgumentTypeError(f'{s!r} is not {what} (must be finite)')
    return v


def finite_float(s: str) -> float:
    """Any finite number."""
    return _number(float, s, 'a finite number')


def positive_float(s: str) -> float:
    """Return a finite number > 0."""
    v = _number(float, s, 'a positive number')
    if not v > 0:
        raise argparse.ArgumentTypeError(f'{s!r} must be > 0')
    return v


def nonneg_float(s: str) -> float:
    """Return a finite number >= 0."""
    v = _number(float, s, 'a number >= 0')
    if v < 0:
        raise argparse.ArgumentTypeError(f'{s!r} must be >= 0')
    return v


def positive_int(s: str) -> int:
    """Return a whole number >= 1."""
    v = _number(int, s, 'a whole number')
    if v < 1:
        raise argparse.ArgumentTypeError(f'{s!r} must be >= 1')
    return v


def nonneg_int(s: str) -> int:
    """Return a whole number >= 0."""
    v = _number(int, s, 'a whole number')
    if v < 0:
        raise argparse.ArgumentTypeError(f'{s!r} must be >= 0')
    return v


def bounded(kind, lo: float, hi: float, what: str = 'value'):
    """
    Return a type accepting kind(s) within [lo, hi], e.g.

    ``bounded(float, 1e-4, 3600, 'dt [s]')``.
    """
    def parse(s: str):
        v = _number(kind, s, f'a {what}')
        if not lo <= v <= hi:
            raise argparse.ArgumentTypeError(f'{what} {s!r} is outside [{lo:g}, {hi:g}]')
        return v
    parse.__name__ = what
    return parse


STRICT_HELP = ('make any WARNING about the recordings an error (exit status 2): inconsistent '
               'channels (a heading flip, a position jump or outlier, a clock reset, astern '
               'motion with the propeller ahead), a column in a likely wrong unit, a file '
               'skipped; without it they are cut out or left out with the WARNING line')


CUT_HELP = ('cut every trial from S seconds (default 5) before EVENT: rudder_first_over (the '
            'first held helm order; real runs start with a manually steered approach) or '
            'propeller_first_astern; a trial without the event is kept whole, with a note')


def event_cut(s: str) -> str:
    """Check EVENT or EVENT:S of --cut-from-event (data.load.parse_event_cut); return it."""
    from mmg_tuner.data.load import parse_event_cut
    from mmg_tuner.errors import ConfigError
    try:
        event, before_s = parse_event_cut(s)
    except ConfigError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None
    return f'{event}:{before_s:g}'
