"""
Input files and trial names that cannot hurt the reader.

Only regular files of a bounded size are opened (a FIFO blocks, /dev/zero never ends), and every
trial name is printable UTF-8 text, unique among the trials read together.
"""
from __future__ import annotations

import os
from pathlib import Path
import re
import stat
from typing import TYPE_CHECKING

from mmg_tuner.errors import TrialDataError

if TYPE_CHECKING:   # annotations only: the trial module imports this one
    from mmg_tuner.data.trial import Trial


def _why(exc: BaseException) -> str:
    return getattr(exc, 'strerror', None) or str(exc) or type(exc).__name__


def check_regular_file(path: Path, what: str = 'file', max_bytes: int | None = None) -> int:
    """
    Return the size of ``path`` [bytes] if it is a regular file of at most max_bytes.

    The size of ``path`` [bytes] if it is a regular file (not a FIFO, device or socket that would
    block or never end) of at most max_bytes; else a TrialDataError.
    """
    try:
        st = os.stat(path)
    except OSError as exc:
        raise TrialDataError(f'{path}: cannot read {what} ({_why(exc)})') from None
    if not stat.S_ISREG(st.st_mode):
        raise TrialDataError(f'{path}: not a regular file (a FIFO, device or socket): '
                             f'refused as a {what}')
    if max_bytes is not None and st.st_size > max_bytes:
        raise TrialDataError(f'{path}: {st.st_size / 1e6:.0f} MB is more than the '
                             f'{max_bytes / 1e6:.0f} MB a {what} may have')
    return st.st_size


_UNSAFE = re.compile(r'[\x00-\x1f\x7f/\\]')


def display_text(text: str) -> str:
    """
    Return ``text`` as valid UTF-8 text.

    ``text`` (e.g. a path whose bytes are not UTF-8, which Python keeps as surrogate escapes) as
    valid UTF-8 text: undecodable bytes become U+FFFD.
    """
    return os.fsencode(text).decode('utf-8', 'replace') if isinstance(text, str) else str(text)


def safe_name(name: str) -> str:
    """
    Return a trial name fit for reports and file names.

    Valid UTF-8, no control characters or path separators (each becomes '_'), never empty.
    """
    return _UNSAFE.sub('_', display_text(name)).strip() or 'trial'


def unique_names(trials: list[Trial], sources: list[str] | None = None) -> list[Trial]:
    """
    Give trials that share a name distinct names, deterministically.

    Give trials that share a name (e.g. turning.csv in two folders) distinct names,
    deterministically: first ``folder/name`` from the folder each came from, then a numeric suffix
    _2, _3 ... in input order. A renamed trial gets a note. Returns the same list.
    """
    seen: dict[str, int] = {}
    for tr in trials:
        seen[tr.name] = seen.get(tr.name, 0) + 1
    taken = set(seen)
    for tr in trials:
        if seen[tr.name] < 2:
            continue
        folder = safe_name(Path(tr.source).parent.name) if tr.source else ''
        cand = f'{folder}/{tr.name}' if folder else tr.name
        base, k = cand, 1
        while cand in taken:
            k += 1
            cand = f'{base}_{k}'
        taken.add(cand)
        tr.notes.append(f'renamed from {tr.name!r} to {cand!r}: another trial read with it '
                        'has the same name')
        tr.name = cand
    return trials


MAX_MESSAGE_CHARS = 600   # a reason inside an error line: what a terminal shows in a few rows
_NUMBER = re.compile(r'[-+]?\d+(?:\.\d+)?(?:e[-+]?\d+)?')


def brief(items: list[str], max_chars: int = MAX_MESSAGE_CHARS) -> str:
    """
    Join items into one readable line: repeats counted, the whole capped at max_chars.

    Items that differ only in their numbers ('gap of 1.0 s at t = 3.0 s', '... t = 7.0 s') are
    one kind: the first is shown with '(and N more like it)'. Kinds beyond max_chars are
    counted, not shown (a recording with time in milliseconds once gave a 710 KB line).
    """
    kinds: dict[str, list[str]] = {}
    for it in items:
        kinds.setdefault(_NUMBER.sub('#', it), []).append(it)
    parts = [v[0] + (f' (and {len(v) - 1} more like it)' if len(v) > 1 else '')
             for v in kinds.values()]
    out: list[str] = []
    used = 0
    for k, p in enumerate(parts):
        if out and used + len(p) + 2 > max_chars:
            out.append(f'... and {len(parts) - k} more kind(s) of note')
            break
        if len(p) > max_chars:
            p = p[:max_chars - 3] + '...'
        out.append(p)
        used += len(p) + 2
    return '; '.join(out)
