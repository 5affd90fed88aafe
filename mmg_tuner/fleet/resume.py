"""
Resuming a fleet.

A ship is done when OUT/<ship>/fleet_ship.json records a finished run whose input digest equals the
current one; everything else is (re)done.

The digest is a SHA-256 over the ship's options (the manifest entry with every default
filled in), the ship config's and overlays' bytes, and the bytes of every file of every
trial source (folders walked in sorted order, names relative to the source), plus the
package version. Changing a bag, an option or the ship config redoes that ship alone; so
does moving its trials (their absolute paths are options too). The record is written last,
atomically, after the ship's files: a run killed before it leaves the ship undone, and the next
run redoes it.
"""
from __future__ import annotations

from dataclasses import dataclass
import hashlib
import json
from pathlib import Path
from typing import Any, TYPE_CHECKING

import mmg_tuner
from mmg_tuner._limits import load_json
from mmg_tuner.core.ship import resolve_config_path
from mmg_tuner.errors import ConfigError, OutputError
from mmg_tuner.fleet.manifest import ShipJob

if TYPE_CHECKING:   # annotations only
    from hashlib import _Hash

RECORD = 'fleet_ship.json'
FLEET_MARK = '.mmg_fleet'        # marks a folder as a fleet's output (resume allowed)
_CHUNK = 1 << 20


def _file_digest(h: _Hash, path: Path) -> None:
    with open(path, 'rb') as f:
        while chunk := f.read(_CHUNK):
            h.update(chunk)


def input_digest(job: ShipJob) -> str:
    """
    Content hash of everything the ship's results depend on (see the module docstring).

    A missing input hashes as missing: the ship then fails with its reason, and is retried when the
    input appears.
    """
    h = hashlib.sha256()
    h.update(json.dumps({'version': mmg_tuner.__version__, 'options': job.options_doc()},
                        sort_keys=True, default=str).encode())
    try:
        ship_file = resolve_config_path(job.ship)
    except ConfigError:
        ship_file = None
    for label, p in (('ship', ship_file), ('params', job.params), ('topics', job.topics)):
        h.update(f'\0{label}\0'.encode())
        if p is not None and Path(p).is_file():
            _file_digest(h, Path(p))
        else:
            h.update(b'<none>' if p is None else b'<missing>')
    for src in job.tune + job.test:
        root = Path(src.path)
        h.update(f'\0source\0{root}\0'.encode())
        if root.is_file():
            _file_digest(h, root)
        elif root.is_dir():
            for f in sorted(p for p in root.rglob('*') if p.is_file()):
                h.update(f'\0{f.relative_to(root).as_posix()}\0'.encode())
                _file_digest(h, f)
        else:
            h.update(b'<missing>')
    return h.hexdigest()


@dataclass
class ShipRecord:
    """What OUT/<ship>/fleet_ship.json says about the last run of a ship."""

    name: str
    digest: str
    status: str                   # 'ok' | 'failed'
    files: list[str]
    summary: dict[str, Any] | None = None
    failure: dict[str, str] | None = None
    wall_s: float = 0.0            # compute time of the ship's tasks (summed)
    stage_s: dict[str, float] | None = None    # per stage: tune, diagnose, evaluate [s]
    finished: str = ''

    def to_json(self) -> str:
        return json.dumps(self.__dict__, indent=1, default=_jsonable) + '\n'


def _jsonable(o: object) -> object:
    import numpy as np
    if isinstance(o, (np.floating, np.integer)):
        return o.item()
    if isinstance(o, np.ndarray):
        return o.tolist()
    return str(o)


def read_record(ship_dir: Path) -> ShipRecord | None:
    """
    Return the ship's record, or None when there is none or it is unreadable.

    The ship's record, or None when there is none or it is unreadable (then the ship is simply
    redone).
    """
    p = Path(ship_dir) / RECORD
    try:
        doc = load_json(p, 'fleet record', limit=1 << 20)   # size and depth limits
        rec = ShipRecord(**doc)
    except (ConfigError, TypeError):
        return None
    # the files a rerun deletes when it does not rewrite them: only plain relative paths inside
    # the ship's folder (a record edited to name '../x' or '/x' is no record of ours)
    if not isinstance(rec.files, list) or not all(
            isinstance(f, str) and f and not Path(f).is_absolute() and '..' not in Path(f).parts
            for f in rec.files):
        return None
    return rec


def up_to_date(ship_dir: Path, digest: str) -> ShipRecord | None:
    """Return the record when the ship finished with these inputs and all its files are there."""
    rec = read_record(ship_dir)
    if rec is None or rec.status != 'ok' or rec.digest != digest:
        return None
    if not all((Path(ship_dir) / f).is_file() for f in rec.files):
        return None
    return rec


def check_fleet_dir(out: Path) -> bool:
    """
    Whether ``out`` may be used: new, empty, or an earlier fleet's output (then it is resumed).

    Anything else is refused: a fleet never writes among a user's files.
    """
    out = Path(out)
    if out.exists() and not out.is_dir():
        raise OutputError(f'--out {out} is an existing file, not a folder')
    if not out.is_dir():
        return False
    if (out / FLEET_MARK).is_file():
        return True
    others = [p.name for p in out.iterdir() if not p.name.startswith('.mmg_tuner.lock')]
    if others:
        raise OutputError(f'--out {out} exists, is not empty ({len(others)} entries, e.g. '
                          f'{sorted(others)[0]!r}) and is not a fleet output; nothing is '
                          'overwritten: choose a new folder')
    return False
