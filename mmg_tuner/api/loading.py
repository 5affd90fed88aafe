"""Load ships, models and trials as the commands do."""
from __future__ import annotations

from dataclasses import replace
import logging
from pathlib import Path
from typing import cast, Sequence

from mmg_tuner._ship_params import load_ship_with_params
from mmg_tuner.api._common import _check, _finite
from mmg_tuner.core.limits import input_limits
from mmg_tuner.core.ship import ShipConfig
from mmg_tuner.data import load as _load
from mmg_tuner.data.consistency import refuse_warnings, warn_rpm_units, WarningLog
from mmg_tuner.data.topics import load_topic_map
from mmg_tuner.data.trial import Trial
from mmg_tuner.errors import ConfigError
from mmg_tuner.learn.model import load_model as _load_model
from mmg_tuner.learn.model import Model


logger = logging.getLogger('mmg_tuner.api')   # one logger for the API, as before the split


def load_ship(name_or_path: str | Path = 'suzaku', params: str | Path | None = None
              ) -> ShipConfig:
    """
    Return a ship config by name (``'suzaku'``, ``'kvlcc2'``) or YAML path.

    ``params`` overlays a params.yaml (e.g. a tuned one). Tuned values in memory:
    ``ship.with_params(fit.params)``.
    """
    return load_ship_with_params(name_or_path, params)   # refuses another ship's params


def load_model(name_or_path: str | Path = 'suzaku', params: str | Path | None = None) -> Model:
    """
    Return a model: the ship with ``params`` overlaid and the residual network it names.

    A params.yaml written by ``tune --residual`` names a network beside it; the model then
    simulates as the hybrid (or the pure network). Without one it is the physics alone.
    """
    return _load_model(name_or_path, params)


def load_trials(paths: str | Path | Sequence[str | Path], ship: ShipConfig | None = None, *,
                dt: float | None = None, topics: str | Path | None = None,
                trial_scale: str = 'ship', keep_astern: bool | None = None,
                cut_from_event: str | tuple[str, float] | None = None,
                strict: bool = False) -> list[Trial]:
    """
    Read every trial in ``paths`` as the commands read them.

    Every trial in ``paths`` (rosbag2 folders, .mcap, .csv, MARIN .dat, or folders of them,
    searched recursively), as the commands read them: resampled on ``dt`` [s] (default: the topic
    map's, 1 s; MARIN files keep their own rate unless dt is given), and with
    ``trial_scale='full'`` Froude-scaled from full scale to the ship's scale
    (``ship.scale_ratio``).

    keep_astern: keep astern propeller and u <= 0 samples. None (default): what the ship's
    family can simulate (``ship.family.astern_rpm and astern_surge``, e.g. lowspeed); without
    a ship, or for a family that cannot, they are left out with a note. True with a ship whose
    family cannot simulate them is refused.
    cut_from_event: 'EVENT' or 'EVENT:SECONDS' (or a tuple) cuts each trial from SECONDS
    (default 5) before the event, one of ``rudder_first_over`` (real runs start with a
    manually steered approach) or ``propeller_first_astern``; a trial without the event is
    kept whole with a note.
    strict: any ``WARNING:`` line logged while reading (channels that disagree, a column in a
    likely wrong unit, a file skipped) is a TrialDataError instead (``--strict``). With a ship,
    an rpm channel that looks like rev/s (its resistance balances the propeller at ~60 times
    the logged rpm: ``data.consistency.rpm_unit_warning``) is one such line per trial.
    """
    if isinstance(paths, (str, Path)):
        paths = [paths]
    fam = ship.family if ship is not None else None
    covers = fam is not None and fam.astern_rpm and fam.astern_surge
    if keep_astern is None:
        keep_astern = covers
    elif keep_astern and fam is not None and not covers:
        name = cast(ShipConfig, ship).name   # (fam is the ship's)
        raise ConfigError(f'keep_astern=True: the {fam.name} family of {name} cannot '
                          'simulate astern propeller or u <= 0 (they are left out with a note '
                          'by default); use a ship of a family that covers them, e.g. lowspeed')
    cut = None
    if cut_from_event is not None:
        cut = (_load.parse_event_cut(f'{cut_from_event[0]}:{cut_from_event[1]}')
               if isinstance(cut_from_event, tuple) else _load.parse_event_cut(cut_from_event))
    if dt is not None:
        _check('dt', dt, _finite(dt) and 1e-3 <= dt <= 600, 'a step in [0.001, 600] s')
    if trial_scale not in ('ship', 'full'):
        raise ConfigError(f"trial_scale {trial_scale!r}: use 'ship' or 'full'")
    if trial_scale == 'full' and ship is None:
        raise ConfigError("trial_scale='full' needs the ship (its scale_ratio)")
    tm = load_topic_map(topics)
    if dt:
        tm = replace(tm, dt=dt)
    # one call: names unique across all paths; samples the ship cannot show dropped with a note
    limits = input_limits(ship) if ship is not None else None
    with WarningLog() as log:
        trials: list[Trial] = _load.load_many(list(paths), tm, keep_astern=bool(keep_astern),
                                              limits=limits)
        if ship is not None and any(t.inputs for t in trials):   # a craft's own channels
            from mmg_tuner.data.channel_units import channel_unit_warnings, warn_all
            for t in trials:
                warn_all(channel_unit_warnings(t, ship), logger)
        if ship is not None:   # rpm logged as rev/s, from the ship's own force balance
            warn_rpm_units(trials, ship)
    if strict:
        refuse_warnings(log.lines)
    if cut is not None:
        trials = _load.cut_at_event(trials, *cut)
        for t in trials:
            if t.notes and t.notes[-1].startswith('not cut:'):
                logger.warning('%s: %s', t.name, t.notes[-1])
    if trial_scale == 'full' and cast(ShipConfig, ship).scale_ratio != 1.0:
        # (ship given: 'full' without it was refused above)
        ratio = cast(ShipConfig, ship).scale_ratio
        trials = [t.froude_scaled(ratio) for t in trials]
    if dt:
        trials = [t if abs(t.dt - dt) < 1e-9 else t.resampled(dt) for t in trials]
    return trials
