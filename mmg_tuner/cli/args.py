"""
Argparse value types that validate at the edge.

Every option is checked once, here, with a message naming the option's value (argparse adds the
option's name), before any work starts.
"""
from __future__ import annotations

import argparse
import math
from typing import Callable, TypeVar

N = TypeVar('N', int, float)
"""The kind of number an option takes."""


def _number(kind: Callable[[str], N], s: str, what: str) -> N:
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


def _at_least(kind: Callable[[str], N], s: str, what: str, lo: int, strict: bool = False) -> N:
    """Return kind(s) if it is >= lo (> lo if strict), else raise naming the bound."""
    v = _number(kind, s, what)
    if v < lo or (strict and v == lo):   # finite (_number): the same as not v > lo
        raise argparse.ArgumentTypeError(f"{s!r} must be {'>' if strict else '>='} {lo}")
    return v


def positive_float(s: str) -> float:
    """Return a finite number > 0."""
    return _at_least(float, s, 'a positive number', 0, strict=True)


def nonneg_float(s: str) -> float:
    """Return a finite number >= 0."""
    return _at_least(float, s, 'a number >= 0', 0)


def positive_int(s: str) -> int:
    """Return a whole number >= 1."""
    return _at_least(int, s, 'a whole number', 1)


def nonneg_int(s: str) -> int:
    """Return a whole number >= 0."""
    return _at_least(int, s, 'a whole number', 0)


def bounded(kind: Callable[[str], N], lo: float, hi: float, what: str = 'value'
            ) -> Callable[[str], N]:
    """
    Return a type accepting kind(s) within [lo, hi], e.g.

    ``bounded(float, 1e-4, 3600, 'dt [s]')``.
    """
    def parse(s: str) -> N:
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


TOPICS_HELP = ('topic map YAML for bags (default: conventions.md topics; a topic left open is '
               'found by type when unambiguous)')


def add_reading_options(ap: argparse.ArgumentParser, dt: Callable[[str], float], dt_help: str,
                        dt_default: float | None = None, scale: bool = True) -> None:
    """
    Add the options of how recordings are read, the same in every command that reads them.

    --topics, --dt (value type dt, default dt_default), --trial-scale (scale), --cut-from-event,
    --strict.
    """
    ap.add_argument('--topics', help=TOPICS_HELP)
    ap.add_argument('--dt', type=dt, default=dt_default, help=dt_help)
    if scale:
        ap.add_argument('--trial-scale', choices=('ship', 'full'), default='ship',
                        help="'full': trials are full scale, Froude-scale them to the ship "
                        'config')
    ap.add_argument('--cut-from-event', type=event_cut, metavar='EVENT[:S]', help=CUT_HELP)
    ap.add_argument('--strict', action='store_true', help=STRICT_HELP)


def add_writing_options(ap: argparse.ArgumentParser, quiet_help: str) -> None:
    """Add --no-plots, --quiet and --write-unphysical (commands that write a tuned model)."""
    ap.add_argument('--no-plots', action='store_true')
    ap.add_argument('--quiet', action='store_true', help=quiet_help)
    ap.add_argument('--write-unphysical', action='store_true',
                    help='write params.yaml even when the model cannot be a ship (a mass '
                    'matrix not positive definite, a negative resistance) or diverges on '
                    'its trials; each failure is marked in the report (default: refused '
                    'with an ERROR naming it)')
