"""Atomic file writes, usable from every layer (imports only the standard library)."""
from __future__ import annotations

import os
from pathlib import Path
import tempfile


def umask() -> int:
    """Return the file-mode creation mask (read without changing it where Linux says it)."""
    try:
        with open('/proc/self/status', encoding='ascii') as f:
            for line in f:
                if line.startswith('Umask:'):
                    return int(line.split()[1], 8)
    except (OSError, ValueError, IndexError):
        pass
    mask = os.umask(0o022)   # elsewhere: set and restore at once
    os.umask(mask)
    return mask


def file_mode() -> int:
    """Return the mode ``open(path, 'w')`` would give a new file: 0o666 less the umask."""
    return 0o666 & ~umask()


def write_atomic(path: str | Path, data: str | bytes) -> None:
    """
    Write so that readers see the old file or the new one, never half of it.

    The file gets the mode the umask gives a new file (mkstemp's temporary file is 0600).
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f'.{path.name}.', suffix='.tmp')
    try:
        os.fchmod(fd, file_mode())
        with os.fdopen(fd, 'wb' if isinstance(data, bytes) else 'w') as f:
            f.write(data)
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise
