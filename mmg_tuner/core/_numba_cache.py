"""
Numba's on-disk cache, keyed by the package version and a hash of the core's sources.

Numba invalidates a cached kernel when *its own* source file changes, not when a module it
imports does (a family's forces, a parameter index in ``layout``, a flag in a registry):
after an upgrade it would run stale machine code. So before any kernel is decorated, point
``numba.config.CACHE_DIR`` at a folder named by ``mmg_tuner.__version__``, numba's version
and a hash of every ``.py`` file under ``mmg_tuner/core`` and of every plugin family or
actuator module (and a plugin actuator's ``EFFECTS`` module): any change there starts a fresh
cache. Base folder: ``$NUMBA_CACHE_DIR`` if
set, else ``$XDG_CACHE_HOME/mmg_tuner`` (``~/.cache/mmg_tuner``) if writable, else
``core/__pycache__``, else the temp dir.

Inside that folder a kernel's file is found by its path *within the package* (``core/models``),
not by its absolute path as numba does (:class:`PackageLocator`): the same sources installed
twice (the colcon install and the source tree the tests import, a venv and a ROS overlay) then
share one compiled copy instead of compiling every kernel again, about 15 s each. The key above
already names the sources, and numba still checks each file's content hash.
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
                out += _effects_companion(mod, Path(spec.origin))
    return out


def _effects_companion(mod: str, origin: Path) -> list[Path]:
    """Return the plugin actuator's ``EFFECTS`` module (its effects add slots to the layout)."""
    import ast
    import importlib.util
    for node in ast.parse(origin.read_text()).body:
        if (isinstance(node, ast.Assign) and len(node.targets) == 1
                and getattr(node.targets[0], 'id', None) == 'EFFECTS'
                and isinstance(node.value, ast.Constant) and isinstance(node.value.value, str)):
            name = node.value.value
            full = name if '.' in name else f'{mod.rsplit(".", 1)[0]}.{name}'
            try:
                spec = importlib.util.find_spec(full)
            except (ImportError, ValueError):
                return []
            if spec is not None and spec.origin and spec.origin.endswith('.py'):
                return [Path(spec.origin)]
    return []


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


def _inside_package(py_file: str) -> Path | None:
    """Folder of py_file relative to this mmg_tuner package, or None outside it."""
    try:
        return Path(py_file).resolve().parent.relative_to(CORE_DIR.parent)
    except (OSError, ValueError):
        return None


def _install_locator() -> None:
    """
    Put :class:`PackageLocator` first in numba's cache locators (once).

    numba has no public hook for this (``CacheImpl._locator_classes``, ``_CacheImpl`` before
    0.61); on a numba without it the kernels still cache, only per installation path.
    """
    try:
        from numba import config
        from numba.core import caching
        impl = getattr(caching, 'CacheImpl', None) or getattr(caching, '_CacheImpl')
        locators = impl._locator_classes
        base = caching.UserProvidedCacheLocator
    except (ImportError, AttributeError):
        return
    if any(getattr(c, 'mmg_tuner_package_locator', False) for c in locators):
        return

    class PackageLocator(base):  # type: ignore[misc, valid-type]  # numba's untyped class
        """numba's user-folder locator, keyed by the file's folder within the package."""

        mmg_tuner_package_locator = True

        def __init__(self, py_func: object, py_file: str) -> None:
            super().__init__(py_func, py_file)
            rel = _inside_package(py_file)
            self._cache_path = os.path.join(
                config.CACHE_DIR, 'package',  # type: ignore[attr-defined]  # set at run time
                *(rel.parts if rel else ()))

        @classmethod
        def from_function(cls, py_func: object, py_file: str) -> object:
            if _inside_package(py_file) is None:
                return None   # a plugin in another folder: numba's own locators
            return super().from_function(py_func, py_file)

    locators.insert(0, PackageLocator)


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
    user_cache = Path(os.environ.get('XDG_CACHE_HOME') or Path.home() / '.cache')
    bases = ([Path(_BASE_ENV)] if _BASE_ENV else
             [user_cache / 'mmg_tuner', CORE_DIR / '__pycache__',
              Path(tempfile.gettempdir()) / f'mmg_tuner-{os.getuid()}'])
    for base in bases:
        if _writable(base / key):
            return base / key
    return bases[-1] / key  # numba then falls back to its own locators


def configure() -> None:
    """Set numba's cache folder (idempotent; call before importing any kernel module)."""
    import numba
    numba.config.CACHE_DIR = str(cache_dir())  # type: ignore[attr-defined]  # set at run time
    _install_locator()
