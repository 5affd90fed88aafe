"""
Numba's on-disk cache, keyed by the package version and a hash of the core's sources.

Numba invalidates a cached kernel when *its own* source file changes, not when a module it
imports does (a family's forces, a parameter index in ``layout``, a flag in a registry):
after an upgrade it would run stale machine code. So before any kernel is decorated, point
``numba.config.CACHE_DIR`` at a folder named by ``mmg_tuner.__version__``, numba's version
and a hash of every ``.py`` file under ``mmg_tuner/core`` and of every plugin family or
actuator module: any change there starts a fresh cache. Base folder: ``$NUMBA_CACHE_DIR`` if
set, else ``core/__pycache__`` (numba's usual place) if writable, else ``~/.cache/mmg_tuner``,
else the temp dir.
"""
from __future__ import annotations

import hashlib
import os
from pathlib import Path
import tempfile

CORE_DIR = Path(__file__).resolve().parent
_BASE_ENV = os.environ.get('NUMBA_CACHE_DIR', '')  # as given before configure() ran


def _plugin_sources() -> list[Path]:
    """Source files of the registered plugin families and actuators (``core/plugins.py``)."""
    import importlib.util

    from mmg_tuner.core import plugins
    out = []
    for kind in ('families', 'actuators'):
        for mod in plugins.modules(kind):
            try:
                spec = importlib.util.find_spec(mod)
            except (ImportError, ValueError):
                spec = None
            if spec is not None and spec.origin and spec.origin.endswith('.py'):
                out.append(Path(spec.origin))
    return out


def source_hash(core_dir: Path = CORE_DIR) -> str:
    """sha256 over the path and bytes of every .py file under core_dir and of the plugins."""
    h = hashlib.sha256()
    files = [(str(f.relative_to(core_dir)), f) for f in sorted(core_dir.rglob('*.py'))]
    files += [(str(f), f) for f in _plugin_sources()]
    for name, f in files:
        h.update(name.encode())
        h.update(b'\0')
        h.update(f.read_bytes())
        h.update(b'\0')
    return h.hexdigest()


def _writable(d: Path) -> bool:
    try:
        d.mkdir(parents=True, exist_ok=True)
        tempfile.TemporaryFile(dir=d).close()
        return True
    except OSError:
        return False


def cache_dir() -> Path:
    """Return the folder this installation's kernels cache into (created if needed)."""
    import numba

    from mmg_tuner import __version__
    key = f'mmg_tuner-{__version__}-numba-{numba.__version__}-{source_hash()[:16]}'
    bases = ([Path(_BASE_ENV)] if _BASE_ENV else
             [CORE_DIR / '__pycache__', Path.home() / '.cache' / 'mmg_tuner',
              Path(tempfile.gettempdir()) / f'mmg_tuner-{os.getuid()}'])
    for base in bases:
        if _writable(base / key):
            return base / key
    return bases[-1] / key  # numba then falls back to its own locators


def configure() -> None:
    """Set numba's cache folder (idempotent; call before importing any kernel module)."""
    import numba
    numba.config.CACHE_DIR = str(cache_dir())  # type: ignore[attr-defined]  # set at run time
