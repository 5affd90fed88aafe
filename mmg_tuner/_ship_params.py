"""
A ship with a params file overlaid, refused when the file was tuned for another ship.

``tune`` and ``diagnose`` write ``ship: NAME`` into params.yaml; values tuned for one hull are
nonsense on another (R_0 of a 320 m tanker on a 3 m model), so a file naming another ship is
refused instead of applied. Used by the API, the commands and the ROS nodes (every layer).
"""
from __future__ import annotations

from pathlib import Path

from mmg_tuner._limits import clip, load_yaml
from mmg_tuner.core.plausibility import warn_once
from mmg_tuner.core.ship import load_ship, ShipConfig
from mmg_tuner.errors import ConfigError


def params_file_ship(path: str | Path) -> str | None:
    """
    Return the ship a params file says it was tuned for (key ``ship``), None when it says none.

    Call after the file was read once (:func:`load_ship` checks it is a readable YAML mapping).
    """
    doc = load_yaml(path, 'params file')   # the limits of _limits.py
    name = doc.get('ship') if isinstance(doc, dict) else None
    if name is not None and not isinstance(name, str):
        raise ConfigError(f'{path}: key "ship" = {clip(repr(name))} must be a ship name (e.g. '
                          'suzaku)')
    return name


def check_params_ship(ship: ShipConfig, params_file: str | Path) -> None:
    """Raise a ConfigError naming both ships and the file when params_file is another ship's."""
    tuned_for = params_file_ship(params_file)
    if tuned_for is not None and tuned_for != ship.name:
        raise ConfigError(
            f'{params_file}: these parameters were tuned for ship {tuned_for!r} (its key '
            f'"ship"), not for {ship.name!r} ({ship.source}); give the ship {tuned_for!r} '
            f'(--ship {tuned_for}, or the ship parameter of a node), or a params file tuned '
            f'for {ship.name!r}')


def load_ship_with_params(name_or_path: str | Path = 'suzaku',
                          params_file: str | Path | None = None) -> ShipConfig:
    """:func:`mmg_tuner.core.ship.load_ship`, refusing a params file tuned for another ship."""
    ship = load_ship(name_or_path, params_file)
    if params_file is not None:
        check_params_ship(ship, params_file)
    # implausible (a sign, instability, a wrong-way turn): one WARNING line each, once
    warn_once(ship, ship.name if params_file is None else f'{ship.name} with {params_file}')
    return ship
