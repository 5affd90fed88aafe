"""
Shared CLI plumbing.

Error reporting, argparse that reports through it, and single output files that are checked before
the work starts and never replace a file this run did not make.
"""
from __future__ import annotations

import argparse
import errno
import math
import os
from pathlib import Path
import sys
import tempfile
from typing import Any, Callable, cast, NoReturn, Protocol

from mmg_tuner._atomic import file_mode
from mmg_tuner._limits import one_line
from mmg_tuner.cli.args import bounded
from mmg_tuner.core.limits import FN_TOP, input_limits
from mmg_tuner.core.ship import ShipConfig
from mmg_tuner.errors import MmgTunerError, OutputError

# the most samples one simulated or generated run may hold: 1e7 x 9 float64 columns is 720 MB
# in memory and ~1 GB of CSV; more is a mistyped --dt or --duration, not a manoeuvre
MAX_RUN_SAMPLES = 10_000_000
SEED = bounded(int, 0, 2**31 - 1, 'seed')


class UsageError(MmgTunerError):
    """A command-line option is malformed or out of range."""


class HelpFormatter(argparse.ArgumentDefaultsHelpFormatter):
    """
    Append ``(default: X)`` to an option's help only when it says something.

    Not when the help already states its default in words, nor for None, an empty list or a
    flag's False (``--help`` used to print both, e.g. "(default: the ship's) (default: None)").
    """

    def _get_help_string(self, action: argparse.Action) -> str | None:
        text = action.help or ''
        d = action.default
        if 'default' in text or d is None or d is argparse.SUPPRESS or d == [] or d is False:
            return text
        return super()._get_help_string(action)


class Parser(argparse.ArgumentParser):
    """Argparse whose errors become one ``ERROR: ...`` line with exit status 2 (run_command)."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        kwargs.setdefault('formatter_class', HelpFormatter)
        super().__init__(*args, **kwargs)

    def error(self, message: str) -> NoReturn:
        raise UsageError(f'{self.prog}: {message} (see {self.prog} --help)')


def run_command(command: Callable[[list[str] | None], int], argv: list[str] | None) -> int:
    """Call command(argv); a MmgTunerError becomes 'ERROR: ...' and exit status 2."""
    _never_fail_printing()
    try:
        return command(argv)
    except MmgTunerError as exc:  # one line of at most a screen, whatever a message quotes
        print(f'ERROR: {one_line(str(exc))}', file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print('interrupted', file=sys.stderr)
        return 130


class ProgressCallback(Protocol):
    """A progress callback (one progress item per call) and its bar's ``close()``."""

    def __call__(self, item: Any) -> None: ...

    def close(self) -> None: ...


def progress_bar(total: int, unit: str, show: Callable[[Any, Any], None],
                 **tqdm_options: Any) -> ProgressCallback:
    """
    Return a progress callback drawing a tqdm bar on stderr; call its ``close()`` at the end.

    show(bar, item) moves the bar for one progress item (an outcome, a CMA-ES generation).
    """
    from tqdm import tqdm
    bar = tqdm(total=total, unit=unit, file=sys.stderr, dynamic_ncols=True, **tqdm_options)

    def update(item: Any) -> None:
        show(bar, item)

    update.close = bar.close  # type: ignore[attr-defined]
    return cast(ProgressCallback, update)   # (its close attached above)


def _never_fail_printing() -> None:
    """
    Print a message even when a file name in it is not UTF-8.

    A file name that is not UTF-8 (kept by Python as surrogate escapes) must not crash a message
    about it: print it with backslash escapes instead.
    """
    for stream in (sys.stdout, sys.stderr):
        try:
            # (a TextIOWrapper's; another stream raises AttributeError, caught below)
            stream.reconfigure(errors='backslashreplace')  # type: ignore[union-attr]
        except (AttributeError, ValueError, OSError):  # not a TextIOWrapper (e.g. replaced)
            pass


def check_samples(n: float, what: str, limit: int = MAX_RUN_SAMPLES) -> int:
    """N samples as an int, or a UsageError naming what asked for them when n > limit."""
    if not n <= limit:
        raise UsageError(f'{what} gives {n:.4g} samples, more than the {limit:.0e} one run '
                         'may hold: use a larger step or a shorter duration')
    return int(n)


def check_new_file(path: str | Path, option: str) -> Path:
    """
    Check, before the work starts, that ``path`` can be written as a new file.

    Refuses an existing file or folder (nothing is overwritten) and a location that is not
    writable. Creates missing parent folders.
    """
    path = Path(path)
    if path.is_dir():
        raise OutputError(f'{option} {path} is an existing folder; give a file name')
    if os.path.lexists(path):
        raise OutputError(f'{option} {path} exists; nothing is overwritten: choose a new name '
                          'or remove it first')
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, probe = tempfile.mkstemp(dir=path.parent, prefix='.write_probe.')
        os.close(fd)
        os.unlink(probe)  # our own probe file, created just above
    except OSError as exc:
        raise OutputError(f'{option} {path}: cannot write there ({exc.strerror or exc})') from None
    return path


def write_new_file(path: str | Path, data: str | bytes, option: str) -> Path:
    """
    Write ``data`` as the new file ``path``, atomically and without replacing anything.

    The text goes to a temporary file that is then hard-linked into place (which fails if the name
    was taken meanwhile). Failures raise an OutputError saying nothing was written.
    """
    path = Path(path)
    tmp = None
    try:
        fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f'.{path.name}.', suffix='.tmp')
        os.fchmod(fd, file_mode())   # the umask's mode, not mkstemp's 0600
        with os.fdopen(fd, 'wb' if isinstance(data, bytes) else 'w', encoding=None
                       if isinstance(data, bytes) else 'utf-8') as f:
            f.write(data)
        try:
            os.link(tmp, path)
        except OSError as exc:  # a file system without hard links: exclusive create instead
            if exc.errno not in (errno.EPERM, errno.ENOTSUP, errno.EOPNOTSUPP, errno.EXDEV):
                raise
            with open(path, 'xb') as out, open(tmp, 'rb') as src:
                out.write(src.read())
    except FileExistsError:
        raise OutputError(f'{option} {path} appeared while this run worked; nothing is '
                          'overwritten and nothing was written') from None
    except OSError as exc:
        raise OutputError(f'writing {option} {path} failed ({exc.strerror or exc}); nothing '
                          'was written') from None
    finally:
        if tmp is not None and os.path.exists(tmp):
            os.unlink(tmp)  # our own temporary file
    return path


def check_run(ship: ShipConfig, rpm: float, speed_ms: float, speed_opt: str,
              rudders: list[tuple[str, float]]) -> None:
    """
    Refuse, before any work, what the ship cannot plausibly do (core/limits.py).

    An rpm beyond its plausible maximum, a speed beyond its top speed, a rudder beyond its steering
    limit. rudders: (option as given, rudder angle [deg]) pairs.
    """
    lim = input_limits(ship)
    problem = lim.channel('rpm').problem(rpm)
    if problem:
        raise UsageError(f'--rpm: {problem} for {ship.name}')
    if speed_ms > lim.top_speed_ms:
        raise UsageError(f'{speed_opt}: {speed_ms:g} m/s exceeds the plausible top speed of '
                         f'{ship.name}, {lim.top_speed_ms:.1f} m/s (Froude number {FN_TOP:g})')
    limit_deg = math.degrees(lim.channel('rudder').limit)
    for opt, deg in rudders:
        if abs(deg) > limit_deg + 1e-9:
            raise UsageError(f'{opt}: rudder {deg:g} deg exceeds the {ship.name} steering '
                             f'limit of {limit_deg:.1f} deg')
