"""
Output folders a command owns.

Checked before the work starts, locked against a second run, written atomically, and never holding
a user's file that the run did not create.

Imports only the standard library and errors.py, so every layer may use it.

Examples
--------
>>> out = OutputDir.open('tuned')            # refuses a non-empty folder or a file
>>> out.write_text('report.md', text)         # atomic; remembered in out.written
>>> out.close()

"""
from __future__ import annotations

import errno
import fcntl
import os
from pathlib import Path
import tempfile
import weakref

from mmg_tuner._atomic import write_atomic
from mmg_tuner.errors import OutputError

LOCK_NAME = '.mmg_tuner.lock'


class OutputDir:
    """
    A locked output folder.

    Use :meth:`open`; write through :meth:`write_text` /

    :meth:`write_bytes` so that a failure says what was written and where.
    """

    def __init__(self, path: Path, lock_fd: int):
        self.path = path
        self._lock_fd = lock_fd
        self.written: list[Path] = []
        # released (and the lock file removed) also when a caller forgets close or the
        # interpreter exits with the folder open
        self._finalizer = weakref.finalize(self, _release, path / LOCK_NAME, lock_fd, os.getpid())

    @classmethod
    def open(cls, path: str | Path, *, resume: bool = False, option: str = '--out',  # noqa: A003
             resumable: bool = True) -> 'OutputDir':
        """
        Create or reuse ``path`` as this run's output folder.

        A path that is a file, a folder that is not writable, a non-empty folder (unless
        ``resume``: the run continues its own earlier output) and a folder another run holds
        are refused with an :class:`OutputError` naming the option and path.
        """
        path = Path(path)
        if path.exists() and not path.is_dir():
            raise OutputError(f'{option} {path} is an existing file, not a folder')
        if path.is_dir() and not resume:
            others = [p.name for p in path.iterdir() if p.name != LOCK_NAME]
            if others:
                raise OutputError(
                    f'{option} {path} exists and is not empty ({len(others)} entries, e.g. '
                    f'{sorted(others)[0]!r}); nothing is overwritten: choose a new folder'
                    + (' or continue it with --resume' if option == '--out' and resumable
                       else ''))
        try:
            path.mkdir(parents=True, exist_ok=True)
            probe_fd, probe = tempfile.mkstemp(dir=path, prefix='.write_probe.')
            os.close(probe_fd)
            os.unlink(probe)  # our own probe file, created just above
        except OSError as exc:
            raise OutputError(f'{option} {path}: cannot write there ({exc.strerror})') from None
        for _ in range(100):   # the lock file a finishing run removed: lock the new one
            try:
                fd = os.open(path / LOCK_NAME, os.O_RDWR | os.O_CREAT, 0o644)
            except OSError as exc:
                raise OutputError(f'{option} {path}: cannot write there '
                                  f'({exc.strerror})') from None
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except OSError as exc:
                os.close(fd)
                if exc.errno in (errno.EWOULDBLOCK, errno.EAGAIN, errno.EACCES):
                    raise OutputError(f'{option} {path} is in use by another running command; '
                                      'wait for it or choose another folder') from None
                raise
            if _same_file(fd, path / LOCK_NAME):
                return cls(path, fd)
            os.close(fd)   # locked a file another run removed on finishing: try again
        raise OutputError(f'{option} {path}: its lock file keeps changing; another command '
                          'is using the folder: choose another one')

    def _write(self, name: str | Path, data: str | bytes) -> Path:
        target = self.path / name
        try:
            write_atomic(target, data)
        except OSError as exc:
            done = ', '.join(str(p.relative_to(self.path)) for p in self.written) or 'nothing'
            raise OutputError(f'writing {target} failed ({exc.strerror or exc}); written so far '
                              f'in {self.path}: {done}') from None
        if target not in self.written:
            self.written.append(target)
        return target

    def write_text(self, name: str | Path, text: str) -> Path:
        """Write a text file atomically inside the folder; returns its path."""
        return self._write(name, text)

    def write_bytes(self, name: str | Path, data: bytes) -> Path:
        """Write a binary file atomically inside the folder; returns its path."""
        return self._write(name, data)

    def close(self) -> None:
        """
        Release the lock and remove the lock file.

        Removed while still locked; a run that opened it meanwhile sees that the file it
        locked is no longer the folder's and locks the new one (:meth:`open`).
        """
        if self._lock_fd >= 0:
            self._finalizer.detach()
            _release(self.path / LOCK_NAME, self._lock_fd, os.getpid())
            self._lock_fd = -1

    def __enter__(self) -> 'OutputDir':
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def _same_file(fd: int, path: Path) -> bool:
    """Whether the open ``fd`` is the file now at ``path`` (not one removed meanwhile)."""
    try:
        a, b = os.fstat(fd), os.stat(path)
    except OSError:
        return False
    return (a.st_dev, a.st_ino) == (b.st_dev, b.st_ino)


def _release(lock: Path, fd: int, pid: int) -> None:
    """Remove our lock file (while holding it) and close it; never raises (nor in a fork)."""
    try:
        if os.getpid() == pid and _same_file(fd, lock):
            os.unlink(lock)
    except OSError:
        pass
    try:
        os.close(fd)
    except OSError:
        pass
