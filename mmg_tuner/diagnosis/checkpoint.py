"""
Checkpoint of a diagnosis: every completed tuning, stored atomically as JSON.

Moved from ``select.py`` unchanged.
"""
from __future__ import annotations

from dataclasses import asdict
import hashlib
import json
from pathlib import Path

from mmg_tuner._atomic import write_atomic
from mmg_tuner._limits import json_loads
from mmg_tuner.core.ship import ShipConfig
from mmg_tuner.diagnosis.settings import DiagnosisSettings
from mmg_tuner.errors import DiagnosisError, OutputError
from mmg_tuner.tuning.objective import Objective
from mmg_tuner.tuning.tuner import refuse_pickle
import numpy as np


class SearchCheckpoint:
    """
    Completed tunings of one diagnosis, written atomically (JSON, data only) after each.

    A resumed search replays the same (deterministic) steps and takes every finished tuning from
    here.
    """

    VERSION = 2       # version 1 was a pickle: refused unread (unpickling runs code)
    FORMAT = 'mmg_tuner diagnosis checkpoint'

    def __init__(self, path: str | Path | None, fingerprint: str, resume: bool = False):
        self.path = Path(path) if path else None
        self.fingerprint = fingerprint
        self.done: dict[str, np.ndarray] = {}
        self.hits = 0
        if resume and self.path is not None and self.path.is_file():
            self.done = self._read(self.path)
        if self.path is not None and not self.done:
            self._write(self.path)   # exists from the start: an interrupt at once still leaves one

    def _read(self, path: Path) -> dict[str, np.ndarray]:
        """Return the stored tunings, checked: every failure a DiagnosisError naming the file."""
        try:
            blob = path.read_bytes()
        except OSError as exc:
            raise DiagnosisError(f'{path}: unreadable checkpoint '
                                 f'({exc.strerror or exc})') from None
        refuse_pickle(path, blob[:4], DiagnosisError)
        try:   # size and nesting checked before parsing (_limits.py)
            doc = json_loads(blob, path, error=DiagnosisError, what='checkpoint')
        except DiagnosisError as exc:   # JSON and UTF-8 errors alike
            raise DiagnosisError(f'{exc}; re-run without --resume') from None
        if not isinstance(doc, dict) or doc.get('format') != self.FORMAT:
            raise DiagnosisError(f'{path}: not a diagnosis checkpoint of mmg_tuner; re-run '
                                 'without --resume')
        if doc.get('version') != self.VERSION:
            raise DiagnosisError(f"{path}: checkpoint version {doc.get('version')}, this "
                                 f'mmg_tuner reads version {self.VERSION}; re-run without '
                                 '--resume')
        if doc.get('fingerprint') != self.fingerprint:
            raise DiagnosisError(f'{path}: the checkpoint belongs to another diagnosis '
                                 '(ship, trials or settings differ)')
        done = doc.get('done')
        if not isinstance(done, dict):
            raise DiagnosisError(f"{path}: damaged checkpoint ('done' is not a mapping)")
        out = {}
        for key, theta in done.items():
            ok = (isinstance(theta, list) and len(theta) > 0
                  and all(isinstance(x, (int, float)) and not isinstance(x, bool)
                          for x in theta))
            if not ok:
                raise DiagnosisError(f'{path}: damaged checkpoint (entry {key[:12]}... is '
                                     'not a list of numbers); re-run without --resume')
            out[key] = np.array(theta, dtype=float)
        return out

    @property
    def base_tune_path(self) -> Path | None:
        """Where the base tuning (the longest single run) checkpoints every generation."""
        return None if self.path is None else self.path.with_name(self.path.stem + '.base.npz')

    @staticmethod
    def key(*parts: object) -> str:
        h = hashlib.sha256()
        for p in parts:
            h.update(p.tobytes() if isinstance(p, np.ndarray) else repr(p).encode())
            h.update(b'|')
        return h.hexdigest()

    def get(self, key: str) -> np.ndarray | None:
        theta = self.done.get(key)
        if theta is not None:
            self.hits += 1
            return theta.copy()
        return None

    def put(self, key: str, theta: np.ndarray) -> None:
        self.done[key] = np.array(theta, dtype=float)
        if self.path is not None:
            self._write(self.path)

    def _write(self, path: Path) -> None:
        # json writes a float as its shortest repr: read back to the same bits
        doc = {'format': self.FORMAT, 'version': self.VERSION, 'fingerprint': self.fingerprint,
               'done': {k: v.tolist() for k, v in self.done.items()}}
        try:
            write_atomic(path, json.dumps(doc) + '\n')
        except OSError as exc:
            raise OutputError(f'writing the diagnosis checkpoint {path} failed '
                              f'({exc.strerror or exc})') from None


def fingerprint(ship: ShipConfig, obj: Objective, obj_test: Objective,
                s: DiagnosisSettings) -> str:
    """Return what a checkpoint must match: ship parameters, trials, weights and settings."""
    return SearchCheckpoint.key(ship.model, ship.params, obj.batch.meas, obj.batch.ctrls,
                                obj_test.batch.meas, obj_test.batch.ctrls,
                                repr(sorted(asdict(s).items())))
