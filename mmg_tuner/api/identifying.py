"""The identify workflow: a control-oriented model, local -> global."""
from __future__ import annotations

from dataclasses import dataclass
import logging
from pathlib import Path
from typing import Any, Sequence

from mmg_tuner.api._common import _as_list, _check, _config, _finite, _is_int
from mmg_tuner.core.layout import INTEGRATORS
from mmg_tuner.core.ship import ShipConfig
from mmg_tuner.data.trial import Trial
from mmg_tuner.errors import TuningError
from mmg_tuner.tuning.lo_go import (BollardTable, check_bollard_table, GO_RIDGE, IdentifyResult,
                                    METHODS, read_bollard_table)
from mmg_tuner.tuning.lo_go import identify as _identify
import numpy as np


logger = logging.getLogger('mmg_tuner.api')   # one logger for the API, as before the split


@dataclass(frozen=True)
class IdentifyConfig:
    """
    Options of :func:`identify` (``tune --method``/``--bollard-pull``), validated on creation.

    method: 'lo' (the local step: one linear least-squares problem), 'go' (the global step from
    the ship's values) or 'lo-go' (GO from LO, pulled toward it; MBPE-LOGO); bollard_pull: a
    bollard-pull table (CSV path with columns n,thrust [rev/s, N per thruster], or a
    ``BollardTable``; None: keep the ship's thrust curve); thrust_degree: the polynomial's
    degree (None: by leave-one-out error, <= 5); targets: the hull coefficients (None: the
    family's); smooth_s: Savitzky-Golay window on the velocities before LO [s] (0: none);
    ridge: GO's pull toward its start per squared relative change (``GO_RIDGE``);
    segment_s: GO simulates pieces of this length from the measured state (0: whole trials,
    single shooting); integrator, substeps: GO's simulation (substeps None: steps of at most
    0.1 s); max_iter: GO's Levenberg-Marquardt iterations; grow: add the trials one by one
    (the paper's Algorithm 1).
    """

    method: str = 'lo-go'
    bollard_pull: str | Path | BollardTable | None = None
    thrust_degree: int | None = None
    targets: tuple[str, ...] | None = None
    smooth_s: float = 2.0
    ridge: float = GO_RIDGE
    segment_s: float = 20.0
    integrator: str = 'rk4'
    substeps: int | None = None
    max_iter: int = 40
    grow: bool = False

    def __post_init__(self) -> None:
        E = TuningError
        _check('method', self.method, self.method in METHODS, f'one of {list(METHODS)}', E)
        _check('thrust_degree', self.thrust_degree, self.thrust_degree is None or (
            _is_int(self.thrust_degree) and 1 <= self.thrust_degree <= 5),
            'a whole number in [1, 5] (or None: chosen by leave-one-out error)', E)
        for name in ('smooth_s', 'ridge', 'segment_s'):
            v = getattr(self, name)
            _check(name, v, _finite(v) and v >= 0, 'a finite number >= 0', E)
        _check('integrator', self.integrator, self.integrator in INTEGRATORS,
               f'one of {sorted(INTEGRATORS)}', E)
        _check('substeps', self.substeps, self.substeps is None or (
            _is_int(self.substeps) and 1 <= self.substeps <= 1000),
            'a whole number in [1, 1000] (or None: steps of at most 0.1 s)', E)
        _check('max_iter', self.max_iter, _is_int(self.max_iter) and self.max_iter >= 1,
               'a whole number >= 1', E)
        if self.targets is not None:
            _check('targets', self.targets, len(self.targets) > 0 and all(
                isinstance(t, str) for t in self.targets), 'a non-empty list of names', E)
            object.__setattr__(self, 'targets', tuple(self.targets))


def identify(ship: ShipConfig, trials: Trial | Sequence[Trial],
             config: IdentifyConfig | None = None, **options: Any) -> IdentifyResult:
    """
    Identify a control-oriented model local -> global (MBPE-LOGO, ``tuning/lo_go.py``).

    The thrust polynomial from the bollard table, the azimuth dynamics from command and
    feedback (when recorded), then the hull coefficients by LO, GO or LO -> GO. ``options``
    are :class:`IdentifyConfig` fields. ``result.write(out)`` writes params.yaml (loaded by
    ``load_ship(name, 'out/params.yaml')``), identify.md and identify.json.

    Examples
    --------
    >>> ship = mt.load_ship('qiuxin_tug')
    >>> res = mt.identify(ship, trials, bollard_pull='bollard.csv', method='lo-go')
    >>> res.write('identified')

    """
    cfg = _config(IdentifyConfig, config, options)
    trials = _as_list(trials)
    table = cfg.bollard_pull
    if table is not None and not isinstance(table, BollardTable):
        table = read_bollard_table(table)
    elif isinstance(table, BollardTable):
        table = check_bollard_table(np.concatenate([-table.astern_n, table.n]),
                                    np.concatenate([table.astern_thrust, table.thrust]),
                                    table.source or 'bollard table')
    return _identify(ship, trials, cfg.method, table, cfg.thrust_degree, cfg.targets,
                     cfg.smooth_s, cfg.ridge, cfg.segment_s, cfg.integrator, cfg.substeps,
                     cfg.max_iter, cfg.grow)
