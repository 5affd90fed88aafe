"""
What ``export`` needs of ``twin_azimuth``: its states, inputs and step as CasADi expressions.

The actuator declares this module (``SYMBOLIC`` in ``twin_azimuth.py``); ``api/exporting.py``
builds the exported model from it and from the family's own functions, so nothing above the
core names the craft. The protocol is in ``core/actuators/__init__.py``; ``sym`` below is the
exporter's builder: ``sym.ca`` (the casadi module), ``sym.param(name)`` (a parameter's value)
and ``sym.symbolic(fn)`` (a compiled function's Python source on CasADi symbols).

Only what branches on a value is written out again with ``casadi.if_else`` (the sign-aware
thrust curve, the rate-limited azimuth step); test/api/test_export.py holds it to the
simulator's step.
"""
from __future__ import annotations

from typing import Any, Mapping, Sequence

from mmg_tuner.core.actuators import twin_azimuth
from mmg_tuner.core.limits import command_limits
from mmg_tuner.core.ship import ShipConfig

STATES = ('alpha_port', 'alpha_rate_port', 'alpha_stbd', 'alpha_rate_stbd')
STATE_UNITS = ('rad', 'rad/s', 'rad', 'rad/s')
INPUTS = ('n_port', 'n_stbd', 'azimuth_cmd_port', 'azimuth_cmd_stbd')
"""The exported model's inputs: the commands."""
INPUT_UNITS = ('rev/s', 'rev/s', 'rad', 'rad')
ACTING = ('n_port', 'n_stbd', 'azimuth_port', 'azimuth_stbd')
"""What ``nu_dot`` takes: the values acting (no drive)."""
ACTING_UNITS = ('rev/s', 'rev/s', 'rad', 'rad')
ACTING_MEANING = 'shaft speeds and the azimuth angles acting (no drive)'
REFERENCE_POINT = "the tug's CO"
"""Where the model's body axes sit (model.json's frames)."""


def thrust(sym: Any, n: Any, side: str) -> Any:
    """Sign-aware thrust [N] of one thruster (twin_azimuth.thrust, times its scale)."""
    ca = sym.ca
    a = ca.fabs(n)
    c = [sym.param(f'thrust_p{k}') for k in range(6)]
    f = c[0] + a * (c[1] + a * (c[2] + a * (c[3] + a * (c[4] + a * c[5]))))
    f = ca.if_else(n > 0.0, f, ca.if_else(n < 0.0, -f * sym.param('thrust_astern_ratio'), 0.0))
    return f * sym.param(f'thrust_scale_{side}')


def outputs(sym: Any, acting: Sequence[Any]) -> tuple[Any, ...]:
    """Return what the family reads (its ``act``) for the values acting."""
    return (thrust(sym, acting[0], 'port'), thrust(sym, acting[1], 'stbd'),
            acting[2] + sym.param('azimuth_offset_port'),
            acting[3] + sym.param('azimuth_offset_stbd'))


def _follow(sym: Any, angle: Any, rate: Any, cmd: Any, phi: tuple[Any, ...],
            h: Any) -> tuple[Any, Any]:
    """twin_azimuth._follow: one thruster's (angle, rate) over a step h."""
    ca = sym.ca
    e = angle - cmd
    new = cmd + phi[0] * e + phi[1] * rate
    w = phi[2] * e + phi[3] * rate
    rmax = sym.param('azimuth_rate_max')
    if rmax > 0.0:
        k1, k2 = sym.param('azimuth_k1'), sym.param('azimuth_k2')
        if k1 > 0.0 and k2 > 0.0:   # the loop asks the motor for more than its top rate
            lag = ca.exp(-k2 * h)
            s = ca.if_else(e > 0.0, -rmax, rmax)
            sat = ca.fabs(k1 / k2 * e) > rmax
            w = ca.if_else(sat, s + (rate - s) * lag, w)
            slew = angle + s * h + (rate - s) * (1.0 - lag) / k2
            slew = ca.if_else((slew - cmd) * e < 0.0, cmd, slew)   # not past the command
            new = ca.if_else(sat, slew, new)
        w = ca.if_else(w > rmax, rmax, ca.if_else(w < -rmax, -rmax, w))
        lim = rmax * h
        move = new - angle
        new = ca.if_else(move > lim, angle + lim, ca.if_else(move < -lim, angle - lim, new))
    return new, w


def step(sym: Any, xa: Sequence[Any], u: Sequence[Any], dt: Any
         ) -> tuple[list[Any], tuple[Any, ...]]:
    """Return (the states after a step of dt, the outputs acting over it), as the simulator."""
    k1 = sym.param('azimuth_k1')
    transition = sym.symbolic(twin_azimuth.transition)
    phi = transition(k1, sym.param('azimuth_k2'), dt) if k1 > 0.0 else (0.0,) * 4
    ap, wp = _follow(sym, xa[0], xa[1], u[2], phi, dt)
    ast, ws = _follow(sym, xa[2], xa[3], u[3], phi, dt)
    if k1 > 0.0:   # acting over the step: the mean of its start and end
        ap_act, ast_act = 0.5 * (xa[0] + ap), 0.5 * (xa[2] + ast)
    else:   # no drive: the command acts at once
        ap_act, ast_act = ap, ast
    return [ap, wp, ast, ws], outputs(sym, (u[0], u[1], ap_act, ast_act))


def rates(sym: Any, xa: Sequence[Any], u: Sequence[Any]) -> tuple[list[Any], tuple[Any, ...]]:
    """Return (the states' time derivatives, the outputs acting): the continuous model."""
    ca = sym.ca
    k1, k2 = sym.param('azimuth_k1'), sym.param('azimuth_k2')
    rmax = sym.param('azimuth_rate_max')
    if k1 > 0.0:
        ap, ast = xa[0], xa[2]
        out = []
        for a, w, c in ((xa[0], xa[1], u[2]), (xa[2], xa[3], u[3])):
            if rmax > 0.0 and k2 > 0.0:   # the rate asked of the motor is limited
                ask = ca.fmin(ca.fmax(k1 / k2 * (c - a), -rmax), rmax)
                out += [w, k2 * (ask - w)]
            elif rmax > 0.0:   # no motor lag: the rate itself is clipped
                out += [ca.fmin(ca.fmax(w, -rmax), rmax), k1 * (c - a) - k2 * w]
            else:
                out += [w, k1 * (c - a) - k2 * w]
    else:   # no drive: the angle follows its command at once
        ap, ast = u[2], u[3]
        out = [0.0, 0.0, 0.0, 0.0]
    return out, outputs(sym, (u[0], u[1], ap, ast))


# ------------------------------------------------------------------ operating point
def limits(ship: ShipConfig) -> dict[str, float]:
    """Return the command limits written to model.json (and bounding the trim)."""
    lim = command_limits(ship, ('n_port', 'azimuth_port'))
    return {'n_max_rev_s': lim['n_port'].limit, 'azimuth_max_rad': lim['azimuth_port'].limit,
            'azimuth_rate_max_rad_s': ship['azimuth_rate_max']}


def propulsion_max(lim: Mapping[str, float]) -> float:
    """Return the largest propulsion level of :func:`ahead` (the shaft speed limit)."""
    return lim['n_max_rev_s']


def ahead(level: float) -> list[float]:
    """Return the values acting straight ahead at propulsion ``level`` (both shafts)."""
    return [level, level, 0.0, 0.0]


def bounds(lim: Mapping[str, float]) -> dict[str, float]:
    """Return each acting value's bound (|value| <= bound) for the trim."""
    return {'n_port': lim['n_max_rev_s'], 'n_stbd': lim['n_max_rev_s'],
            'azimuth_port': lim['azimuth_max_rad'], 'azimuth_stbd': lim['azimuth_max_rad']}


def at_rest(sym: Any, acting: Mapping[str, float]
            ) -> tuple[list[float], list[float], dict[str, str]]:
    """Return (states, commands, notes for linear.json) holding the values acting steady."""
    ap, ast = acting['azimuth_port'], acting['azimuth_stbd']
    note = 'k1 > 0: alpha = alpha_cmd at rest' if sym.param('azimuth_k1') > 0 else 'no drive'
    return ([ap, 0.0, ast, 0.0], [acting['n_port'], acting['n_stbd'], ap, ast],
            {'azimuth_drive': note})


def document(ship: ShipConfig, lim: Mapping[str, float]) -> dict[str, Any]:
    """Return model.json's description of the actuator (the thruster map)."""
    g = ship.__getitem__
    return {'thrusters': {
        'positions_m': {'port': [g('thruster_x_port'), g('thruster_y_port')],
                        'stbd': [g('thruster_x_stbd'), g('thruster_y_stbd')]},
        'tau': 'X = sum F cos(a), Y = sum F sin(a), N = sum F (l_x sin(a) - l_y cos(a)); '
               'a = alpha + azimuth_offset, 0 = thrust ahead, + = thrust to starboard',
        'thrust_curve': {
            'form': 'F(n) = s (p0 + p1 |n| + ... + p5 |n|^5) for n > 0, -s astern_ratio '
                    '(...) for n < 0, 0 at n = 0; s = thrust_scale of the side [N]',
            'p': [g(f'thrust_p{k}') for k in range(6)],
            'astern_ratio': g('thrust_astern_ratio'),
            'thrust_scale': {'port': g('thrust_scale_port'), 'stbd': g('thrust_scale_stbd')}},
        'azimuth_offset_rad': {'port': g('azimuth_offset_port'),
                               'stbd': g('azimuth_offset_stbd')},
        'azimuth_drive': {
            'form': "alpha'' = k1 (alpha_cmd - alpha) - k2 alpha', |alpha'| <= rate_max "
                    '(0: no limit); the discrete step integrates the linear part exactly '
                    'and applies the angle at the end of the step over it, as the '
                    'simulator does; k1 <= 0: the angle follows its command at once',
            'k1': g('azimuth_k1'), 'k2': g('azimuth_k2'),
            'rate_max_rad_s': g('azimuth_rate_max')},
        'limits': dict(lim)}}
