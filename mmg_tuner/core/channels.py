"""
Named input channels: what drives a simulation, one time series each, with its unit.

A :class:`~mmg_tuner.core.trial.Trial` holds its inputs keyed by channel name; readers map CSV
columns and topic-map entries to these names. The channels a ship needs are its actuators'
inputs (``core/actuators``) plus the environment channels (:data:`ENVIRONMENT`, the measured
wind). The compiled kernels take them as one array ``ctrl`` (T, n) whose columns are the
family's :attr:`~mmg_tuner.core.models.Family.channels`, in that order: the actuators' inputs,
then ``wind_n``, ``wind_e`` (NaN where the wind was not measured: the wind parameters act).

Adding an actuator with new inputs: declare them in the actuator module's ``CHANNELS``
(name -> (unit, description, default[, topic])); the actuator registry adds them to this table,
and a topic map (``data/topics.py``) gets a section for each.
"""
from __future__ import annotations

from dataclasses import dataclass
import math


@dataclass(frozen=True)
class Channel:
    """
    One input channel.

    name: the key in ``Trial.inputs``, CSV headers and topic maps; unit: SI unit (or rev/min,
    rev/s) of the stored values; description: sign convention and meaning; default: the value
    a trial without the channel is given (NaN: "not measured"; None: required, a trial without
    it cannot drive a ship that needs it); topic: the ROS topic a recording carries it on by
    default (a topic map's section of the same name overrides it; '': read only when mapped).
    """

    name: str
    unit: str
    description: str
    default: float | None = None
    topic: str = ''


TABLE: dict[str, Channel] = {c.name: c for c in (
    Channel('rpm', 'rev/min', 'propeller revolutions, + ahead', topic='/propeller_rpm'),
    Channel('rudder', 'rad', 'rudder angle, + turns the ship to starboard',
            topic='/rudder_angle'),
    Channel('bow_thruster', 'rev/s', 'bow tunnel thruster, + pushes the bow to starboard', 0.0,
            '/bow_thruster'),
    Channel('stern_thruster', 'rev/s', 'stern tunnel thruster, + pushes the stern to starboard',
            0.0, '/stern_thruster'),
    Channel('wind_n', 'm/s', 'measured true wind: the air velocity over ground, north',
            math.nan),
    Channel('wind_e', 'm/s', 'measured true wind: the air velocity over ground, east',
            math.nan),
)}
"""Every known channel by name (actuator modules add theirs through the registry)."""

ENVIRONMENT: tuple[str, ...] = ('wind_n', 'wind_e')
"""Channels that are not commands: the last columns of every kernel input array."""

CONTROL_NAMES: tuple[str, ...] = ('rpm', 'rudder')
"""The two channels of a screw-and-rudder ship (the columns of ``Trial.controls``)."""


def add_channel(channel: Channel) -> None:
    """Register a channel (an actuator's input); the same name twice must mean the same."""
    old = TABLE.get(channel.name)
    if old is not None and old != channel:
        raise ValueError(f'channel {channel.name!r} declared twice with different meanings: '
                         f'{old} and {channel}')
    TABLE[channel.name] = channel


def unit(name: str) -> str:
    """Return the unit of channel ``name`` (KeyError naming the known channels if unknown)."""
    try:
        return TABLE[name].unit
    except KeyError:
        raise KeyError(f'unknown input channel {name!r}; known: {", ".join(TABLE)}') from None
