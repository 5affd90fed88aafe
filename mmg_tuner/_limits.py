"""
Readers whose cost is bounded by their input's size: YAML, JSON, ``.npz`` and text lines.

Every file a user can hand over (ship configs, params overlays, topic maps, fleet manifests,
network files, checkpoints, a resumed run's ``args.json``) is read through these, so that a small
hostile file cannot take minutes, gigabytes or a traceback: a YAML alias bomb, JSON nested ten
thousand deep, an ``.npz`` member whose header declares gigabytes or that is not an ``.npy`` at
all. A limit crossed raises the caller's error class with one line naming the file and the limit
(the limits are stated in ``doc/reference/commands.md``, "Input limits").

Imports only the standard library, numpy, PyYAML and errors.py, so every layer (core included)
may use it, as ``_atomic.py``.
"""
from __future__ import annotations

import io
import json
import math
import os
from pathlib import Path
import re
from typing import Any, Callable, Collection
import zipfile
import zlib

from mmg_tuner.errors import ConfigError
import numpy as np
import yaml

MAX_YAML_BYTES = 1 << 20        # 1 MiB: the largest shipped YAML is ~10 kB
MAX_YAML_NODES = 200_000        # scalars + collections after alias expansion
MAX_DEPTH = 100                 # nesting of YAML and JSON collections
MAX_JSON_BYTES = 64 << 20       # 64 MiB: a diagnosis checkpoint.json of many candidates
MAX_NPZ_BYTES = 1 << 30         # 1 GiB: the .npz file itself
MAX_NPZ_MEMBERS = 1000          # members in one .npz archive
MAX_NPY_BYTES = 256 << 20       # 256 MiB: one array, uncompressed
MAX_LINE_CHARS = 1 << 16        # 64 Ki characters: one line of a CSV or text table
MAX_MESSAGE_CHARS = 1000        # one error line is never longer than a screen
QUOTE_CHARS = 80                # what an error line quotes of a file's content

_ZIP_MAGIC = (b'PK\x03\x04', b'PK\x05\x06')
_NPY_MAGIC = b'\x93NUMPY'

ErrorType = Callable[[str], Exception]


def clip(text: Any, limit: int = QUOTE_CHARS) -> str:
    """Return ``str(text)`` cut to ``limit`` characters (``...`` and the length said)."""
    s = str(text)
    if len(s) <= limit:
        return s
    return f'{s[:limit]}... ({len(s)} characters)'


def one_line(message: str, limit: int = MAX_MESSAGE_CHARS) -> str:
    """Return a message as one line of at most ``limit`` characters (a screen)."""
    text = ' '.join(ln.strip() for ln in str(message).splitlines() if ln.strip())
    if len(text) <= limit:
        return text
    return text[:limit - 40] + f' ... [{len(text) - limit + 40} characters cut]'


def _mb(n: float) -> str:
    return f'{n / (1 << 20):.3g} MiB' if n >= 1 << 20 else f'{n / 1024:.3g} KiB'


def read_bytes(path: str | Path, what: str, *, limit: int, error: ErrorType = ConfigError
               ) -> bytes:
    """Return the bytes of a regular file of at most ``limit`` bytes (else ``error``)."""
    path = Path(path)
    if not path.is_file():
        raise error(f'{path}: {what} does not exist or is not a regular file')
    try:
        with open(path, 'rb') as f:   # a buffer of the file's size, not of the limit's
            raw = f.read(min(os.fstat(f.fileno()).st_size, limit) + 1)
    except OSError as exc:
        raise error(f'{path}: cannot read {what} ({exc.strerror or exc})') from None
    if len(raw) > limit:
        raise error(f'{path}: larger than {_mb(limit)}, the limit for a {what}; not one')
    return raw


def read_text(path: str | Path, what: str, *, limit: int, error: ErrorType = ConfigError,
              bom: bool = True) -> str:
    """Return a UTF-8 text file of at most ``limit`` bytes (a byte-order mark skipped)."""
    raw = read_bytes(path, what, limit=limit, error=error)
    try:
        return raw.decode('utf-8-sig' if bom else 'utf-8')
    except UnicodeDecodeError as exc:
        raise error(f'{path}: not UTF-8 text (byte {exc.start}); a {what} is a text '
                    'file') from None


def check_lines(lines: str | list[str], source: str | Path, what: str, *,
                limit: int = MAX_LINE_CHARS, error: ErrorType = ConfigError) -> None:
    """Refuse a text (or its lines) whose longest line exceeds ``limit`` characters."""
    if isinstance(lines, str):
        if len(lines) <= limit:
            return
        lines = lines.splitlines()
    if not lines or max(map(len, lines)) <= limit:
        return
    for k, line in enumerate(lines, 1):
        if len(line) > limit:
            raise error(f'{source}: line {k} has {len(line)} characters, more than the '
                        f'{limit} a line of a {what} may have')


# ---------------------------------------------------------------------------------------- YAML
_BASE_LOADER: Any = getattr(yaml, 'CSafeLoader', yaml.SafeLoader)


class _LimitedLoader(_BASE_LOADER):  # type: ignore[misc]  # libyaml's or PyYAML's: Any
    """
    Safe YAML loader that counts nodes (aliases expanded) and depth while composing.

    The event parser is libyaml's when present; the composer is PyYAML's Python one (libyaml's
    recurses without a limit and crashes on deep nesting), so the checks run before a node
    is built and no document larger than its limits is ever constructed.
    """

    get_single_node = yaml.composer.Composer.get_single_node
    compose_document = yaml.composer.Composer.compose_document
    compose_scalar_node = yaml.composer.Composer.compose_scalar_node
    compose_sequence_node = yaml.composer.Composer.compose_sequence_node
    compose_mapping_node = yaml.composer.Composer.compose_mapping_node

    def __init__(self, stream: str, source: str, error: ErrorType) -> None:
        super().__init__(stream)
        self.anchors: dict[str, Any] = {}
        self._source, self._error = source, error
        self._depth = 0
        self._count = 0
        self._weight: dict[int, int] = {}

    def compose_node(self, parent: Any, index: Any) -> Any:  # noqa: D102
        if self.check_event(yaml.AliasEvent):
            anchor = self.peek_event().anchor
            node = self.anchors.get(anchor)
            if node is not None:
                self._count += self._weight.get(id(node), 1)
                self._check_count()
            return yaml.composer.Composer.compose_node(self, parent, index)
        self._depth += 1
        if self._depth > MAX_DEPTH:
            raise self._error(f'{self._source}: YAML nested deeper than {MAX_DEPTH} levels, the '
                              'limit; not a config file')
        start = self._count
        self._count += 1
        self._check_count()
        node = yaml.composer.Composer.compose_node(self, parent, index)
        self._depth -= 1
        self._weight[id(node)] = self._count - start
        return node

    def _check_count(self) -> None:
        if self._count > MAX_YAML_NODES:
            raise self._error(f'{self._source}: YAML of more than {MAX_YAML_NODES} values '
                              '(an alias *name counted as all it repeats), the limit; not a '
                              'config file')


def yaml_loads(text: str, source: str | Path, *, error: ErrorType = ConfigError) -> Any:
    """Parse one YAML document safely within the depth and expansion limits."""
    if len(text) > MAX_YAML_BYTES:
        raise error(f'{source}: larger than {_mb(MAX_YAML_BYTES)}, the limit for a YAML file')
    loader = _LimitedLoader(text, str(source), error)
    try:
        return loader.get_single_data()
    except yaml.YAMLError as exc:
        raise error(f'{source}: not valid YAML ({clip(one_line(str(exc)), 300)})') from None
    except RecursionError:  # pragma: no cover - MAX_DEPTH stops composing long before
        raise error(f'{source}: YAML nested too deep; not a config file') from None
    finally:
        loader.dispose()


def load_yaml(path: str | Path, what: str, *, error: ErrorType = ConfigError) -> Any:
    """Read and parse a YAML file of at most :data:`MAX_YAML_BYTES` (see :func:`yaml_loads`)."""
    text = read_text(path, what, limit=MAX_YAML_BYTES, error=error)
    return yaml_loads(text, path, error=error)


# ---------------------------------------------------------------------------------------- JSON
_JSON_STRING = re.compile(rb'"(?:[^"\\]|\\.)*"', re.S)
_NOT_BRACKET = bytes(b for b in range(256) if b not in b'[]{}')


def json_depth(raw: bytes) -> int:
    """Deepest nesting of ``[``/``{`` in a JSON text (brackets inside strings not counted)."""
    brackets = _JSON_STRING.sub(b'', raw).translate(None, _NOT_BRACKET)
    if not brackets:
        return 0
    steps = np.frombuffer(brackets, np.uint8)
    depth = np.cumsum(np.where((steps == ord('[')) | (steps == ord('{')), 1, -1))
    return int(depth.max())


def json_loads(text: str | bytes, source: str | Path, *, error: ErrorType = ConfigError,
               limit: int = MAX_JSON_BYTES, what: str = 'JSON') -> Any:
    """Parse JSON after checking its size and nesting depth (never a RecursionError)."""
    raw = text.encode('utf-8', 'surrogatepass') if isinstance(text, str) else bytes(text)
    if len(raw) > limit:
        raise error(f'{source}: {what} larger than {_mb(limit)}, the limit')
    depth = json_depth(raw)
    if depth > MAX_DEPTH:
        raise error(f'{source}: {what} nested {depth} levels deep, more than the limit of '
                    f'{MAX_DEPTH}; not written by mmg_tuner')
    try:
        return json.loads(raw)
    except (ValueError, RecursionError) as exc:
        raise error(f'{source}: {what} is not valid JSON ({clip(exc, 120)})') from None


def json_default(o: Any) -> Any:
    """
    Return numpy scalars and arrays as plain numbers and lists: ``json.dumps``'s ``default``.

    Shared by the writers of reports and network files; anything else stays a TypeError, as
    json.dumps raises without a default.
    """
    if isinstance(o, (np.floating, np.integer)):
        return o.item()
    if isinstance(o, np.ndarray):
        return o.tolist()
    raise TypeError(type(o))


def load_json(path: str | Path, what: str, *, error: ErrorType = ConfigError,
              limit: int = MAX_JSON_BYTES) -> Any:
    """Read and parse a JSON file within the size and depth limits."""
    raw = read_bytes(path, what, limit=limit, error=error)
    return json_loads(raw, path, error=error, limit=limit, what=what)


# ----------------------------------------------------------------------------------------- npz
def read_npz(src: str | Path | bytes, source: str | Path, what: str, *,
             members: Collection[str] | Callable[[str], bool], error: ErrorType = ConfigError,
             max_array_bytes: int = MAX_NPY_BYTES) -> dict[str, np.ndarray]:
    """
    Return the arrays of an ``.npz`` archive, each checked from its header before it is read.

    ``members`` names the arrays the format has (a collection, or a predicate on the name
    without ``.npy``); any other member is refused unread, as is a member that is not an
    ``.npy``, one holding Python objects, or one whose header declares more than
    ``max_array_bytes`` or more than the member holds. Not a zip at all: "not an .npz archive".
    """
    allowed = members if callable(members) else (lambda name: name in members)  # noqa: E731
    head = src[:4] if isinstance(src, bytes) else _head(src, what, error)
    if head not in _ZIP_MAGIC:
        raise error(f'{source}: not an .npz archive (a zip of .npy arrays), so not a {what}')
    try:
        if not isinstance(src, bytes) and Path(src).stat().st_size > MAX_NPZ_BYTES:
            raise error(f'{source}: larger than {_mb(MAX_NPZ_BYTES)}, the limit for a {what}')
        with zipfile.ZipFile(io.BytesIO(src) if isinstance(src, bytes) else src) as zf:
            infos = zf.infolist()
            if len(infos) > MAX_NPZ_MEMBERS:
                raise error(f'{source}: {len(infos)} members, more than the {MAX_NPZ_MEMBERS} '
                            f'an .npz may hold; not a {what}')
            for info in infos:   # every header checked before any array is read
                _check_member(zf, info, source, what, allowed, error, max_array_bytes)
            return {info.filename[:-4]: _read_member(zf, info, source, error)
                    for info in infos}
    except (zipfile.BadZipFile, zlib.error, EOFError, OSError, NotImplementedError,
            ValueError) as exc:
        raise error(f'{source}: damaged .npz archive ({clip(exc, 120)}); not a usable '
                    f'{what}') from None


def _head(path: str | Path, what: str, error: ErrorType) -> bytes:
    if not Path(path).is_file():
        raise error(f'{path}: {what} does not exist or is not a regular file')
    try:
        with open(path, 'rb') as f:
            return f.read(4)
    except OSError as exc:
        raise error(f'{path}: cannot read {what} ({exc.strerror or exc})') from None


def _check_member(zf: zipfile.ZipFile, info: zipfile.ZipInfo, source: str | Path, what: str,
                  allowed: Callable[[str], bool], error: ErrorType, limit: int) -> None:
    name = info.filename
    if not name.endswith('.npy') or not allowed(name[:-4]):
        raise error(f'{source}: member {clip(name, 60)!r} is not one a {what} has; refused '
                    'unread')
    if info.file_size > limit + 4096:
        raise error(f'{source}: member {name!r} declares {_mb(info.file_size)} uncompressed, '
                    f'more than the limit of {_mb(limit)} per array; not read')
    with zf.open(info) as f:
        if f.read(6) != _NPY_MAGIC:
            raise error(f'{source}: member {name!r} is not an .npy array; not a {what}')
        f.seek(0)
        version = np.lib.format.read_magic(f)
        if version == (1, 0):
            shape, _, dtype = np.lib.format.read_array_header_1_0(f)
        elif version == (2, 0):
            shape, _, dtype = np.lib.format.read_array_header_2_0(f)
        else:
            raise error(f'{source}: member {name!r}: .npy format version {version} is not read '
                        f'(1.0 and 2.0 are); not a {what}')
    if dtype.hasobject:
        raise error(f'{source}: member {name!r} holds Python objects (dtype object), which are '
                    f'never loaded; not a {what} written by mmg_tuner')
    nbytes = math.prod(int(n) for n in shape) * dtype.itemsize
    if nbytes > limit:
        raise error(f'{source}: member {name!r} declares shape {clip(shape, 60)} of {dtype} '
                    f'({_mb(nbytes)}), more than the limit of {_mb(limit)} per array; not read')
    if nbytes > info.file_size:
        raise error(f'{source}: member {name!r} declares shape {clip(shape, 60)} of {dtype} '
                    f'but holds {info.file_size} bytes: truncated or damaged')


def _read_member(zf: zipfile.ZipFile, info: zipfile.ZipInfo, source: str | Path,
                 error: ErrorType) -> np.ndarray:
    with zf.open(info) as f:
        return np.lib.format.read_array(f, allow_pickle=False)
