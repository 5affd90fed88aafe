"""
Actuator models: the registry.

An actuator model turns recorded or commanded input channels (``core/channels.py``) into what
the hull model needs: the states the family's force formulas read (propeller revolutions,
the actual rudder angle, thruster speeds; its *outputs*) and, optionally, forces of its own
(a propeller's side force, an azimuth thruster's thrust). It owns its internal states (the
actual rudder angle behind a steering gear, azimuth angles and rates) and the effects that act
between a command and the ship (rpm scale, rudder offset and steering-gear lag belong to the
screw-and-rudder actuator).

A family lists its actuators in ``ACTUATORS``; the outputs of all of them, in that order, form
the actuator tuple ``act`` its ``forces`` read (by position: the family module names them).

How to add an actuator ``myact`` (``tunnel_thrusters.py`` is the shortest template):

1. Write ``core/actuators/myact.py`` (or any module, registered as a plugin:
   ``core/plugins.py``) declaring at the top:

   * ``PARAMS = (...)``: a literal tuple of its own parameter slots (the layout reads it
     without importing the module); effect parameters belong to the effects (below).
   * ``INPUTS``: the channels it reads, in order; ``CHANNELS``: the new ones among them,
     name -> (unit, description, default[, topic]) (default None: required; ``'nan'``:
     optional, NaN where not recorded; topic: the ROS topic a recording carries it on by
     default, '' or left out: read only when a topic map names one).
   * ``OUTPUTS``: names of the values it hands the family, in order; ``STATES``: names of its
     internal states (may be empty). ``DESCRIPTION``: one line with the source.
   * optionally ``COMMANDED``: measured channel -> the channel an interactive simulator
     (``core/stepper.py``) writes its command to, when the actuator's own dynamics move the
     measured value toward a commanded one (an azimuth angle and its command).
   * optionally ``EFFECTS``: the module (beside this one, or a full path) declaring the
     effects that act in this actuator (a tuple ``EFFECTS`` of ``core/effect.Effect``:
     ``twin_azimuth_effects.py``); the effect table (``core/effects.py``) appends them after
     the library's own, their parameters become slots of the layout, the diagnosis searches
     them in any family driven by this actuator. The kernel reads their slots.
   * optionally ``JOINTS``: joint name -> (position state, velocity state) among ``STATES``
     (a 1-tuple: no velocity state, published as NaN), what ``sim_node`` publishes as
     sensor_msgs/JointState (a tug's azimuth angles).
   * optionally ``TRIALS``: the module (beside this one, or a full module path) that says what
     the ``generate`` command sails for a craft this actuator drives, in place of the
     screw-and-rudder manoeuvres (``twin_azimuth_trials.py`` is the example): ``RATE_HZ``
     (default recording rate), ``ASSUMPTIONS`` (a line for trials.yaml; ``{source}``: the
     ship file), ``Noise`` (a ``core/noise.Sigmas`` dataclass with ``apply(trial, rng)``;
     its defaults are the craft's sensors), ``catalogue(ship)`` (dataclasses with ``name``,
     ``role`` ('identification' or 'validation') and ``duration_s``), ``generate(ship, maneuver,
     rate_hz, noise, seed) -> (truth, measured)`` and ``tables(ship, noise, seed)`` (name ->
     (CSV header, rows, description), written beside the trials); optionally ``mirror(ship,
     maneuver)`` (the manoeuvre to the other side, None when it has none). The diagnosis
     advises a trial of this catalogue, its mirror as the held-out twin.
   * optionally ``SYMBOLIC``: the module (beside this one, or a full path) that gives the
     ``export`` command the actuator as CasADi expressions (``twin_azimuth_symbolic.py``:
     ``STATES``, ``INPUTS``, ``ACTING`` and their units, ``REFERENCE_POINT``, ``outputs``,
     ``step``, ``rates``,
     ``limits``, ``propulsion_max``, ``ahead``, ``bounds``, ``at_rest``, ``document``); a
     family driven by it alone whose module has ``hull_document`` can be exported.
   * optionally ``IDENTIFY``: the module (beside this one, or a full path) with what the
     local -> global identification (``tuning/lo_go.py``) fits of the actuator before the
     hull (``twin_azimuth_identify.py``): ``NAME`` (its key in identify.json) and
     ``fit(ship, trials, substeps) -> fit or None``, the fit having ``params``, ``report()``
     and ``describe()``; optionally ``bollard_curve(params, n)``, the thrust [N] a bollard
     table is checked against (``data/channel_units.py``).
   * optionally ``PLAUSIBILITY``: ``{'propulsion': [outputs], 'helm': {output: 'rudder' or a
     fraction}}``, what the stability and turn checks set (``core/plausibility.py``; the
     entry of ``config/model_plausibility.yaml`` wins where it names the actuator; a name
     that is not an output is a ConfigError naming this module).
   * njit functions (``inline='always'``). ``cmd`` is the tuple of this actuator's input
     values (``INPUTS`` order; the plant reads them from the kernels' input array, delayed by
     the time offset), ``a`` the float array of all actuator states, ``i`` the position of
     this actuator's first state in it:

     - ``start(p, cmd, a, i)``: set the internal states from the first sample's inputs;
     - ``hold(p, cmd, h, astern) -> (status, held)``: once per sample
       interval: convert the inputs held over it (``h``: the integration step [s];
       ``astern``: whether the family covers astern revolutions); status ``layout.OK`` or a
       status code that stops the run; ``held`` a tuple of floats for ``output``;
     - ``output(p, held, a, i) -> tuple``: once per integration step: advance the internal
       states over it and return the outputs acting during it (floats, ``len(OUTPUTS)``);
     - optionally ``forces(p, u, v, r, act, k) -> (X, Y, N)``: forces [N] and moment [N m]
       about midship of its own, ``act[k]`` being its first output.
2. Append its name to :data:`REGISTRY` (built-in) or register the plugin; list it in a
   family's ``ACTUATORS``.
"""
from __future__ import annotations

from dataclasses import dataclass, field
import functools
import importlib
import math
from types import ModuleType
from typing import Any, Callable

from mmg_tuner.core._registry import declared, module_name, registry
from mmg_tuner.core.channels import add_channel, Channel

BUILTIN: tuple[str, ...] = ('screw_rudder', 'tunnel_thrusters', 'twin_azimuth',
                            'screw_rudder_tau')
_PLUGINS, REGISTRY = registry(BUILTIN, 'actuators', 'actuator')
"""Registered actuator models, by name."""


@dataclass(frozen=True)
class Actuator:
    """What the rest of the package may ask about an actuator model (module docstring)."""

    name: str
    params: tuple[str, ...]
    inputs: tuple[str, ...]
    outputs: tuple[str, ...]
    states: tuple[str, ...]
    description: str
    start: Callable[..., Any] = field(repr=False)
    hold: Callable[..., Any] = field(repr=False)
    output: Callable[..., Any] = field(repr=False)
    forces: Callable[..., Any] | None = field(default=None, repr=False)
    commanded: dict[str, str] = field(default_factory=dict)
    # its plausibility rules (propulsion outputs, helm) when config/model_plausibility.yaml
    # has no entry for it: a plugin declares its own (core/plausibility.py)
    plausibility: dict[str, Any] = field(default_factory=dict)
    # joint -> (position state, velocity state or '') a simulator publishes (sim_node's
    # JointState)
    joints: dict[str, tuple[str, str]] = field(default_factory=dict)


def module_of(name: str) -> str:
    """Return the module of registered actuator ``name`` (KeyError if there is none)."""
    if name not in REGISTRY:
        raise KeyError(f'unknown actuator {name!r}; registered: {", ".join(REGISTRY)}')
    return module_name(__name__, name, _PLUGINS)


def declared_params(name: str) -> tuple[str, ...]:
    """Return an actuator's own ``PARAMS``, read from its source without importing it."""
    return tuple(declared(module_of(name), 'PARAMS'))


@functools.lru_cache(maxsize=None)   # the registry is fixed at import: parse each source once
def declared_inputs(name: str) -> tuple[str, ...]:
    """Return an actuator's ``INPUTS``, read from its source without importing it."""
    return tuple(declared(module_of(name), 'INPUTS'))


def companion(name: str, key: str) -> str | None:
    """
    Return the module an actuator names under ``key`` (``TRIALS``, ``SYMBOLIC``), or None.

    A name without a dot is a module beside the actuator's own.
    """
    mod = module_of(name)
    decl = declared(mod, key, '')
    if not decl:
        return None
    return str(decl) if '.' in str(decl) else f'{mod.rsplit(".", 1)[0]}.{decl}'


def load_companion(name: str, key: str) -> ModuleType | None:
    """
    Import the module an actuator names under ``key`` (None: it names none).

    A module that cannot be imported is an ImportError naming the actuator's module and the
    declaration, not a bare ModuleNotFoundError from deep in a command.
    """
    module = companion(name, key)
    if module is None:
        return None
    try:
        return importlib.import_module(module)
    except ImportError as exc:
        raise ImportError(f'actuator {name!r} ({module_of(name)}): {key} = {module!r} cannot '
                          f'be imported: {exc}') from exc


@functools.lru_cache(maxsize=None)   # the registry is fixed at import: parse each source once
def commanded_channels() -> frozenset[str]:
    """Return the channels that carry an order the actuators move toward (``COMMANDED``)."""
    return frozenset(str(c) for name in REGISTRY
                     for c in dict(declared(module_of(name), 'COMMANDED', {})).values()
                     if c)


def declared_channels(name: str) -> dict[str, tuple[Any, ...]]:
    """Return an actuator's new ``CHANNELS``, read from its source without importing it."""
    return dict(declared(module_of(name), 'CHANNELS', {}))


_CACHE: dict[str, Actuator] = {}


def actuator(name: str) -> Actuator:
    """Return the registered actuator model called ``name`` (KeyError if there is none)."""
    if name not in _CACHE:
        mod = importlib.import_module(module_of(name))
        _CACHE[name] = Actuator(name, tuple(mod.PARAMS), tuple(mod.INPUTS),
                                tuple(mod.OUTPUTS), tuple(mod.STATES), mod.DESCRIPTION,
                                mod.start, mod.hold, mod.output,
                                getattr(mod, 'forces', None),
                                dict(getattr(mod, 'COMMANDED', {})),
                                dict(getattr(mod, 'PLAUSIBILITY', {})),
                                {str(k): (str(v[0]), str(v[1]) if len(v) > 1 else '')
                                 for k, v in getattr(mod, 'JOINTS', {}).items()})
    return _CACHE[name]


def register_channels() -> None:
    """Add every registered actuator's new channels to the channel table."""
    for name in REGISTRY:
        for ch, decl in declared_channels(name).items():
            unit, description, default = decl[:3]
            if default == 'nan':   # NaN has no literal: 'nan' spells "not recorded"
                default = math.nan
            topic = str(decl[3]) if len(decl) > 3 else ''
            add_channel(Channel(ch, str(unit), str(description), default, topic))


register_channels()
