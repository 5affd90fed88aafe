"""
A model: a ship (its family and parameter values) and, optionally, a learned residual network.

The ship config never owns a network; whatever simulates "a model" takes one of these (or a
bare :class:`~mmg_tuner.core.ship.ShipConfig`, the physics alone).
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from mmg_tuner._ship_params import load_ship_with_params
from mmg_tuner.core.ship import ShipConfig
from mmg_tuner.errors import ConfigError
from mmg_tuner.learn.plausibility import warn_network_once
from mmg_tuner.learn.residual import check_fits, load_residual, model_kind, ResidualNet


@dataclass(frozen=True)
class Model:
    """ship: the physics (family + parameters); residual: its learned residual, or None."""

    ship: ShipConfig
    residual: ResidualNet | None = None

    def __post_init__(self) -> None:
        """Refuse a network trained for a family that reads other channels."""
        if self.residual is not None:
            check_fits(self.residual, self.ship)

    @property
    def kind(self) -> str:
        """'physics', 'hybrid', 'pure network' or 'blend' (:func:`~.residual.model_kind`)."""
        return model_kind(self.residual)

    @property
    def name(self) -> str:
        return self.ship.name


def as_model(model: 'Model | ShipConfig') -> Model:
    """Return a Model from a Model or a bare ship config (the physics alone)."""
    return model if isinstance(model, Model) else Model(model)


def load_model(name_or_path: str | Path = 'suzaku', params_file: str | Path | None = None
               ) -> Model:
    """
    Return the ship, with a params.yaml's values and the residual network it names, if any.

    A params file tuned for another ship (its key ``ship``) is refused, naming both. A network
    whose response to full rudder is implausible (the wrong way, too fast:
    ``learn/plausibility.py``) is loaded with one ``WARNING:`` line each, once.
    """
    ship = load_ship_with_params(name_or_path, params_file)
    net = None if params_file is None else load_residual(params_file)
    if net is not None:
        try:
            check_fits(net, ship)
        except ConfigError as exc:
            raise ConfigError(f'{params_file}: {exc}') from None
        warn_network_once(ship, net, f'{ship.name} with {params_file}')
    return Model(ship, net)
