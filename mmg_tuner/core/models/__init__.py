"""
Model families: the registry.

One family = one module here + one entry in :data:`REGISTRY`.

A family is the part of a ship model that differs between ship models: the hull (and
propeller and rudder) forces, the actuators driving it (``core/actuators``) and, optionally,
its own equations of motion. Everything else is shared and family-blind: the MMG equations of
motion (the default), wind loads and current kinematics (``core/dynamics.py``), effects
(``core/effects.py``), integrators, ``advance``, simulation and the tuning cost
(``core/integrate.py``), and everything above the core (objective, tuning, diagnosis, nodes,
commands), which only ever passes ``ship.kind`` along.

How to add a family ``myship`` (look at ``standard.py``, the shortest, as the template):

1. Write ``core/models/myship.py`` declaring, at the top, in this order:

   * ``PARAMS = ('X_0', ...)`` -- a literal tuple of the parameter names your forces read that
     are not shared (shared: ``layout.SHARED_PARAMS``: particulars, added masses, windage,
     effects). Names another family also declares are the same slot. It must be a literal:
     the layout reads it without importing the module (the kernels need the finished layout).
   * ``REQUIRED``: the keys a ship YAML of this family must give; ``DEFAULTS``: values for
     keys it may omit.
   * ``ACTUATORS``: the actuator models driving it (``core/actuators``), in order; their
     outputs, concatenated, are the actuator tuple ``act`` its forces read, and their inputs
     (plus the measured wind) are the channels a trial must bring.
   * ``ASTERN_RPM`` (bool): whether it covers propeller revolutions <= 0; ``ASTERN_SURGE``
     (bool): whether it covers surge u <= 0. When False, the kernels stop a run there with a
     status (``layout.RPM_NOT_POSITIVE`` / ``SURGE_NOT_POSITIVE``), the data layer and the
     node refuse such inputs; ask via :func:`family`.
   * ``DESCRIPTION``: one line with the source.
   * ``forces(p, u, v, r, act) -> (X, Y, N)``: an ``@njit(cache=True, fastmath=FASTMATH)``
     function returning hull + propeller + rudder (+ thruster) force [N] and yaw moment [N m]
     about midship in body axes, for velocities u, v_m [m/s] through the water, yaw rate r
     [rad/s], the flat parameter vector p (read it by index: ``_X0 = PARAM_INDEX['X_0']`` at
     module level, so numba folds the index in) and the actuator tuple ``act`` (its
     actuators' outputs, by position: name the positions at module level). No inertia
     terms (the equations of motion add them), no effects and no actuator forces (the
     shared hooks and the actuators add them).
   * optionally its own wind model: ``wind(p, wx, wy) -> (X, Y, N)``, an njit function of the
     apparent wind given as the air's velocity relative to the ship in body axes [m/s]
     (without one the shared Blendermann loads act), and ``AIR_DRAG`` (bool, default False):
     whether wind loads act even when the true wind is zero (the ship's own air drag).
   * optionally its own equations of motion (the MMG families use the shared ones of
     ``core/dynamics.py``: the non-dimensional added masses of eq. 7), as two njit functions:
     ``motion(p, u, v, r, X, Y, N) -> (du, dv, dr)``, the accelerations for the hull,
     actuator and effect forces (X, Y, N) (its inertia, Coriolis and centripetal terms
     inside), and ``mass_solve(p, X, Y, N) -> (du, dv, dr)``, M^-1 (X, Y, N) for external
     forces (wind); a control-oriented family supplies M, C(nu) and D(nu) in SI units this
     way (its ``forces`` then return -D(nu) nu, the actuators tau).
   * optionally ``PLAUSIBILITY``: what makes a model of it impossible or implausible
     (``positive``, ``non_negative``, ``non_positive``: parameter names; ``resistance``:
     ``'params'`` or ``'probe'``; ``signs``: name -> -1 or 1), read by
     ``core/plausibility.py`` where ``config/model_plausibility.yaml`` has no entry for the
     family; a name the family does not have is a ConfigError naming this module.
2. Append ``'myship'`` to :data:`BUILTIN` (its position is its integer code ``ship.kind``),
   or register it as a plugin from outside the package (``core/plugins.py``).
3. A ship YAML with ``model: myship``.

Nothing else changes. The whole-run kernels (simulation, tuning cost, manoeuvres) are compiled
once per family: their entry points pass the family's tag (``dynamics.FAMILY_TAGS``, a type
numba specialises on), so only that family's ``forces`` and ``wind`` are inlined, without a
branch. Kernels called with the plain code (``derivative(ship.kind, ...)`` from other compiled
code) branch over the registered families with one ``literal_unroll``. The on-disk kernel cache
is keyed by a hash of the core sources (``core/_numba_cache.py``), so a new or edited family
never runs stale compiled code.
"""
from __future__ import annotations

from dataclasses import dataclass, field
import importlib
from typing import Any, Callable

from mmg_tuner.core._registry import declared, module_name, registry
from mmg_tuner.core.actuators import actuator, declared_params as actuator_params
from mmg_tuner.core.channels import ENVIRONMENT

BUILTIN: tuple[str, ...] = (
    'container', 'standard', 'lowspeed', 'surge_decoupled', 'simplified6',
    'surge_decoupled_rudder')
_PLUGINS, REGISTRY = registry(BUILTIN, 'families', 'family')
"""Registered families; the position is the family's code (built-ins first, then plugins)."""


@dataclass(frozen=True)
class Family:
    """What the rest of the package may ask about a family (see the module docstring)."""

    name: str
    code: int
    params: tuple[str, ...]   # its own PARAMS, then its actuators' (as the layout has them)
    required: tuple[str, ...]
    defaults: dict[str, float]
    actuators: tuple[str, ...]
    astern_rpm: bool
    astern_surge: bool
    description: str
    forces: Callable[..., Any] = field(repr=False)
    wind: Callable[..., Any] | None = field(default=None, repr=False)  # None: Blendermann
    air_drag: bool = False
    motion: Callable[..., Any] | None = field(default=None, repr=False)  # None: MMG eq. 7
    mass_solve: Callable[..., Any] | None = field(default=None, repr=False)
    # its plausibility rules when config/model_plausibility.yaml has no entry for it: a
    # plugin declares its own (core/plausibility.py)
    plausibility: dict[str, Any] = field(default_factory=dict, repr=False)

    @property
    def inputs(self) -> tuple[str, ...]:
        """Return the command channels its actuators read, in kernel order."""
        return tuple(c for a in self.actuators for c in actuator(a).inputs)

    @property
    def channels(self) -> tuple[str, ...]:
        """Return the columns of its kernels' input array: commands, then measured wind."""
        return self.inputs + ENVIRONMENT

    @property
    def outputs(self) -> tuple[str, ...]:
        """Return the actuator tuple its forces read (its actuators' outputs, in order)."""
        return tuple(o for a in self.actuators for o in actuator(a).outputs)


def module_of(name: str) -> str:
    """Return the module of registered family ``name`` (KeyError if there is none)."""
    if name not in REGISTRY:
        raise KeyError(name)
    return module_name(__name__, name, _PLUGINS)


def declared_params(name: str) -> tuple[str, ...]:
    """Return a family's ``PARAMS`` (and its actuators') read from source, without importing."""
    mod = module_of(name)
    own = tuple(declared(mod, 'PARAMS'))
    extra = tuple(q for a in declared(mod, 'ACTUATORS') for q in actuator_params(a))
    return own + tuple(q for q in extra if q not in own)


_CACHE: dict[str, Family] = {}


def family(name: str) -> Family:
    """Return the registered family called ``name`` (KeyError if there is none)."""
    if name not in _CACHE:
        code = REGISTRY.index(name) if name in REGISTRY else None
        if code is None:
            raise KeyError(name)
        mod = importlib.import_module(module_of(name))
        _CACHE[name] = Family(name, code, declared_params(name), tuple(mod.REQUIRED),
                              dict(getattr(mod, 'DEFAULTS', {})), tuple(mod.ACTUATORS),
                              bool(mod.ASTERN_RPM), bool(mod.ASTERN_SURGE), mod.DESCRIPTION,
                              mod.forces, getattr(mod, 'wind', None),
                              bool(getattr(mod, 'AIR_DRAG', False)),
                              getattr(mod, 'motion', None), getattr(mod, 'mass_solve', None),
                              dict(getattr(mod, 'PLAUSIBILITY', {})))
    return _CACHE[name]


def families() -> list[Family]:
    """All registered families, in code order."""
    return [family(n) for n in REGISTRY]


def family_of_code(code: int) -> Family:
    return family(REGISTRY[code])
