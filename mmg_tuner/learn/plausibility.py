"""
Can a network model be a ship? Its response to full rudder each way (issue 45).

A network's weights can be finite and still wild: a hybrid that turns to port under starboard
helm, or reaches 7.5 m/s at its service rpm, runs in silence otherwise. :func:`network_findings`
runs the model as every recorded trial is run (``residual.simulate_segments``, the compiled
hybrid) on two synthetic trials: from the straight run at the service speed
(``core/plausibility.py``: Fn ``service_froude``), the propeller held at the rpm that holds that
speed in the physics, the rudder at ``network.rudder_deg`` (35 deg, the IMO turning test's; the
ship's ``steering.max_rudder_deg`` if less) to starboard and to port for ``network.duration_s``
(config/model_plausibility.yaml). Implausible,
a WARNING with the figure (never an error: the network is the user's to judge): a side that
does not turn its way (heading change and yaw rate at the end), a run that diverges, a speed
beyond ``network.max_speed_ratio`` times the start speed or Fn ``network.max_froude``.

Checked where a network is loaded (``learn.model.load_model``: ``simulate``, ``evaluate``,
``sim_node``, ``replay_node``) and at the API's simulate/evaluate; remembered per network and
model values, so the node's ``/diagnostics`` show it at no cost (``ros/health.py``
``plausibility_status``).
"""
from __future__ import annotations

import logging
import math
import weakref

from mmg_tuner.core.plausibility import _straight_run, Finding, G, tolerances
from mmg_tuner.core.ship import ShipConfig
from mmg_tuner.core.trial import Trial
from mmg_tuner.errors import MmgTunerError
from mmg_tuner.learn.residual import model_kind, ResidualNet, simulate_segments
import numpy as np

logger = logging.getLogger(__name__)

DEFAULTS = {'rudder_deg': 35.0, 'duration_s': 60.0, 'max_speed_ratio': 1.5, 'max_froude': 0.5}


def _settings() -> dict[str, float]:
    given = tolerances().get('network') or {}
    return {k: float(given.get(k, v)) for k, v in DEFAULTS.items()}


def network_findings(ship: ShipConfig, net: ResidualNet | None) -> list[Finding]:
    """
    Return the warnings on ``ship`` + ``net``'s response to full rudder each way ([] if none).

    [] without a network, for a family without rpm and rudder channels (the probe is a
    full rudder; another craft's network is not probed) and when no rpm holds the service
    speed (the physics' own check says so).
    """
    if net is None or not {'rpm', 'rudder'} <= set(ship.family.channels) or \
            'n_P' not in ship.family.outputs:
        return []
    straight = _straight_run(ship)
    if isinstance(straight, Finding):
        return []
    U, act = straight
    rpm = 60.0 * act[ship.family.outputs.index('n_P')]
    cfg = _settings()
    dt = float(net.dt_s)
    T = max(2, int(round(cfg['duration_s'] / dt)) + 1)
    limit = min(cfg['max_speed_ratio'] * U, cfg['max_froude'] * math.sqrt(G * ship.L_pp))
    delta = min(math.radians(cfg['rudder_deg']), ship.max_rudder_rad)
    kind = model_kind(net)
    out: list[Finding] = []
    top = (0.0, '')
    for sign, side in ((1.0, 'starboard'), (-1.0, 'port')):
        trial = Trial(np.arange(T) * dt, np.tile([0.0, 0.0, 0.0, U, 0.0, 0.0], (T, 1)),
                      name=f'full {side} helm',
                      inputs={'rpm': np.full(T, rpm), 'rudder': np.full(T, sign * delta)})
        try:
            states, _, fail_t, why = simulate_segments(ship, net, trial, 'rk4', 0.0)
        except (MmgTunerError, ZeroDivisionError) as exc:
            return [Finding('warning', 'network response', math.nan, f'the {kind} model '
                            f'cannot be run at full helm ({exc}): its response is not checked')]
        what = (f'{T * dt - dt:.0f} s of {math.degrees(sign * delta):+.0f} deg rudder at '
                f'{rpm:.4g} rpm from {U:.3g} m/s')
        speed = np.hypot(states[:, 3], states[:, 4])
        fast = float(np.nanmax(speed)) if np.any(np.isfinite(speed)) else 0.0
        if fast > top[0]:
            top = (fast, what)
        if fail_t is not None:
            out.append(Finding('warning', f'network turn to {side}', fail_t,
                               f'the {kind} model diverges {fail_t:.1f} s into {what} ({why}): '
                               'check the network (retrain it, or simulate the physics alone)'))
            continue
        psi, r = float(states[-1, 2]), float(states[-1, 5])
        if not (sign * psi > 0 and sign * r > 0):
            out.append(Finding('warning', f'network turn to {side}', math.degrees(psi),
                               f'the {kind} model turns the wrong way: {what} give a heading '
                               f'change of {math.degrees(psi):+.1f} deg (yaw rate '
                               f'{math.degrees(r):+.2f} deg/s at the end); {side} helm must '
                               f'turn to {side}: check the network (retrain it, or simulate '
                               'the physics alone)'))
    if top[0] > limit:
        fn = top[0] / math.sqrt(G * ship.L_pp)
        out.append(Finding('warning', 'network speed', top[0],
                           f'the {kind} model reaches {top[0]:.3g} m/s (Fn {fn:.2f}, '
                           f'{top[0] / U:.2g} x its start) in {top[1]}; more than '
                           f'{limit:.3g} m/s ({cfg["max_speed_ratio"]:g} x the start or Fn '
                           f'{cfg["max_froude"]:g}, config/model_plausibility.yaml): a turn '
                           'at constant rpm slows a ship; check the network'))
    return out


# per network (weakly: a network no longer used is forgotten), per model values: (family
# kind, parameter bytes, rudder limit)
_Key = tuple[int, bytes, float]
_CHECKED: weakref.WeakKeyDictionary[ResidualNet, dict[_Key, list[Finding]]] = \
    weakref.WeakKeyDictionary()
_WARNED: weakref.WeakKeyDictionary[ResidualNet, set[_Key]] = weakref.WeakKeyDictionary()


def _key(ship: ShipConfig) -> _Key:
    return (ship.kind, ship.params.tobytes(), ship.max_rudder_rad)


def network_checked(ship: ShipConfig, net: ResidualNet | None) -> list[Finding]:
    """Return :func:`network_findings`, remembered per network and model values."""
    if net is None:
        return []
    per = _CHECKED.setdefault(net, {})
    key = _key(ship)
    if key not in per:
        per[key] = network_findings(ship, net)
    return per[key]


def warn_network_once(ship: ShipConfig, net: ResidualNet | None, source: str = ''
                      ) -> list[Finding]:
    """Log each of :func:`network_checked`'s findings as its ``WARNING:`` line, once."""
    findings = network_checked(ship, net)
    if net is None:
        return findings
    warned = _WARNED.setdefault(net, set())
    key = _key(ship)
    if key not in warned:
        warned.add(key)
        for f in findings:
            logger.warning(f.line(source or ship.name))
    return findings
