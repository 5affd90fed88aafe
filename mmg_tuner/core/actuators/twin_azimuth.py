"""
Actuator ``twin_azimuth``: two azimuth thrusters (port, starboard), thrust and angle dynamics.

Inputs: the shaft speeds ``n_port``, ``n_stbd`` [rev/s, + ahead], the measured azimuth angles
``azimuth_port``, ``azimuth_stbd`` [rad; 0 = thrust ahead, + = thrust toward starboard] and,
optionally, the commanded angles ``azimuth_cmd_port``, ``azimuth_cmd_stbd`` [rad] (NaN or
absent: not recorded). Outputs (what the family and this module's ``forces`` read): the two
thrusts [N] and the two actual angles [rad].

- Thrust per thruster (MBPE-LOGO eq. 20, doc/reference/mbpe_logo_tug.md §1): a polynomial
  of degree <= 5 in the shaft speed, sign-aware so that it covers reverse:
  F(n) = sign(n) (p0 + p1 |n| + ... + p5 |n|^5), times ``thrust_astern_ratio`` for n < 0
  (a propeller gives less thrust astern) and ``thrust_scale_<side>`` (1: a clean propeller;
  below 1: a fouled one). F = k n|n| is p2 = k, the rest 0.
- Azimuth angle (eq. 9 as the reference reads it, low confidence): a second-order response to
  the commanded angle, alpha'' = k1 (alpha_c - alpha) - k2 alpha', with an optional rate limit
  ``azimuth_rate_max`` [rad/s] (0: none) on the rate the position loop asks of the slewing
  motor: alpha'' = k2 (clip((k1 / k2) (alpha_c - alpha), +-rate_max) - alpha'). Its states
  are each thruster's angle and rate. The linear part is integrated exactly over each
  integration step (closed-form 2x2 matrix exponential for a held command), the saturated
  part too (the motor's first-order lag), the regime decided at each step's start; the angle
  acting over a step is the mean of its start and end. When a sample has no command (NaN),
  the measured angle acts directly (rate 0); k1 <= 0 makes the thruster follow its command
  at once. ``azimuth_offset_<side>`` [rad] is added to the angle that acts (a thruster whose
  zero is off).
- Forces (eq. 8): tau = T(alpha) f with the columns [cos a, sin a, l_x sin a - l_y cos a] for
  each thruster at (``thruster_x_<side>``, ``thruster_y_<side>``) [m] from the model's
  reference point (body axes: x forward, y to starboard). With the thrusters aft (l_x < 0), a
  positive azimuth pushes the stern to starboard and turns the ship to port; more thrust on
  the port thruster turns it to starboard.

A craft with two fixed propellers (differential thrust) is this actuator with its azimuths
recorded as 0 (``config/otter_usv.yaml``).
"""
from __future__ import annotations

PARAMS = ('thrust_p0', 'thrust_p1', 'thrust_p2', 'thrust_p3', 'thrust_p4', 'thrust_p5',
          'thrust_astern_ratio', 'azimuth_k1', 'azimuth_k2', 'azimuth_rate_max',
          'thruster_x_port', 'thruster_y_port', 'thruster_x_stbd', 'thruster_y_stbd')
# its effects (declared in twin_azimuth_effects.py, collected by core/effects.py):
# thrust_scale_<side>, azimuth_offset_<side>
EFFECTS = 'twin_azimuth_effects'
INPUTS = ('n_port', 'n_stbd', 'azimuth_port', 'azimuth_stbd', 'azimuth_cmd_port',
          'azimuth_cmd_stbd')
# default topics named as VRX names its thruster topics (osrf/vrx, vrx_urdf/wamv_gazebo/urdf/
# thruster_layouts/wamv_gazebo_thruster_config.xacro: thrusters/<name>/thrust, .../pos); the
# commanded angles are read only where a topic map names their topics
CHANNELS = {
    'n_port': ('rev/s', 'port thruster shaft speed, + thrust ahead at azimuth 0', None,
               '/thrusters/port/thrust'),
    'n_stbd': ('rev/s', 'starboard thruster shaft speed, + thrust ahead at azimuth 0', None,
               '/thrusters/stbd/thrust'),
    'azimuth_port': ('rad', 'port azimuth angle (measured), 0 = thrust ahead, + = thrust '
                     'toward starboard', None, '/thrusters/port/pos'),
    'azimuth_stbd': ('rad', 'starboard azimuth angle (measured), 0 = thrust ahead, + = '
                     'thrust toward starboard', None, '/thrusters/stbd/pos'),
    'azimuth_cmd_port': ('rad', 'port azimuth angle commanded (NaN: not recorded)',
                         'nan'),
    'azimuth_cmd_stbd': ('rad', 'starboard azimuth angle commanded (NaN: not recorded)',
                         'nan'),
}
OUTPUTS = ('thrust_port', 'thrust_stbd', 'alpha_port', 'alpha_stbd')
# an interactive simulator's command of a measured angle goes to its command channel: the angle
# dynamics then move the thruster (core/stepper.py)
COMMANDED = {'azimuth_port': 'azimuth_cmd_port', 'azimuth_stbd': 'azimuth_cmd_stbd'}
STATES = ('alpha_port', 'alpha_rate_port', 'alpha_stbd', 'alpha_rate_stbd')
# the joints a simulator publishes (sim_node: sensor_msgs/JointState), named as VRX names them
JOINTS = {'port_azimuth_joint': ('alpha_port', 'alpha_rate_port'),
          'stbd_azimuth_joint': ('alpha_stbd', 'alpha_rate_stbd')}
# what `generate` sails for a craft it drives: its catalogue, sensor noise and bollard-pull table
TRIALS = 'twin_azimuth_trials'
# what `export` needs: its states, inputs and step as CasADi expressions
SYMBOLIC = 'twin_azimuth_symbolic'
# what `tune --method lo-go` fits of it from commanded and measured angles: the drive's constants
IDENTIFY = 'twin_azimuth_identify'
DESCRIPTION = ('two azimuth thrusters: polynomial thrust in rev/s, second-order angle '
               'dynamics, tau = T(alpha) f (MBPE-LOGO eqs. 8, 9, 20)')

# Neutral values of the slots a ship file may omit (a family using this actuator merges them
# into its DEFAULTS): no rate limit, the same thrust astern. Its effects' neutral values (a
# clean propeller, no offset) come from the effect registry.
DEFAULTS = {'thrust_p0': 0.0, 'thrust_p1': 0.0, 'thrust_p3': 0.0, 'thrust_p4': 0.0,
            'thrust_p5': 0.0, 'thrust_astern_ratio': 1.0, 'azimuth_rate_max': 0.0}

import math  # noqa: E402  (below the declarations the layout reads)
from typing import TYPE_CHECKING  # noqa: E402

from mmg_tuner.core._jit import FASTMATH  # noqa: E402, I100
from mmg_tuner.core.layout import OK, PARAM_INDEX  # noqa: E402
from numba import njit  # noqa: E402

if TYPE_CHECKING:  # annotations only: numba never evaluates them
    from mmg_tuner.core._jit import FloatArray

_P0 = PARAM_INDEX['thrust_p0']   # p0..p5 are consecutive slots (one literal PARAMS tuple)
_ASTERN = PARAM_INDEX['thrust_astern_ratio']
_K1 = PARAM_INDEX['azimuth_k1']
_K2 = PARAM_INDEX['azimuth_k2']
_RMAX = PARAM_INDEX['azimuth_rate_max']
_XP = PARAM_INDEX['thruster_x_port']
_YP = PARAM_INDEX['thruster_y_port']
_XS = PARAM_INDEX['thruster_x_stbd']
_YS = PARAM_INDEX['thruster_y_stbd']
_SP = PARAM_INDEX['thrust_scale_port']
_SS = PARAM_INDEX['thrust_scale_stbd']
_OP = PARAM_INDEX['azimuth_offset_port']
_OS = PARAM_INDEX['azimuth_offset_stbd']
if any(PARAM_INDEX[f'thrust_p{_k}'] != _P0 + _k for _k in range(6)):
    raise ImportError('twin_azimuth: the slots thrust_p0..thrust_p5 must be consecutive '
                      '(another family declares one of them out of order)')


@njit(cache=True, fastmath=FASTMATH, inline='always')
def thrust(p: FloatArray, n: float) -> float:
    """Thrust [N] of one clean thruster at shaft speed n [rev/s] (eq. 20, sign-aware)."""
    a = abs(n)
    f = p[_P0] + a * (p[_P0 + 1] + a * (p[_P0 + 2] + a * (p[_P0 + 3] + a * (
        p[_P0 + 4] + a * p[_P0 + 5]))))
    if n > 0.0:
        return f
    if n < 0.0:
        return -f * p[_ASTERN]
    return 0.0


@njit(cache=True, fastmath=FASTMATH, inline='always')
def transition(k1: float, k2: float, h: float) -> tuple[float, float, float, float, float]:
    """
    exp(A h) for A = [[0, 1], [-k1, -k2]]: (phi11, phi12, phi21, phi22), and exp(-k2 h).

    Cayley-Hamilton: exp(A h) = e^(l h) ((c - l s) I + s A) with l = -k2/2, q = l^2 - k1,
    c = cosh(sqrt(q) h), s = sinh(sqrt(q) h) / sqrt(q) (cos/sin for q < 0; 1, h for q = 0).
    """
    lam = -0.5 * k2
    q = lam * lam - k1
    if q > 0.0:
        mu = math.sqrt(q)
        c = math.cosh(mu * h)
        s = math.sinh(mu * h) / mu
    elif q < 0.0:
        w = math.sqrt(-q)
        c = math.cos(w * h)
        s = math.sin(w * h) / w
    else:
        c = 1.0
        s = h
    e = math.exp(lam * h)
    d = c - lam * s
    return e * d, e * s, -k1 * e * s, e * (d - k2 * s), e * e


@njit(cache=True, fastmath=FASTMATH, inline='always')
def start(p: FloatArray, cmd: tuple[float, ...], a: FloatArray, i: int) -> None:
    """Start each thruster at its first measured angle, at rest."""
    a[i] = cmd[2]
    a[i + 1] = 0.0
    a[i + 2] = cmd[3]
    a[i + 3] = 0.0


@njit(cache=True, fastmath=FASTMATH, inline='always')
def hold(p: FloatArray, cmd: tuple[float, ...], h: float,
         astern: bool) -> tuple[int, tuple[float, ...]]:
    """
    Return (OK, held): the thrusts and what the drive needs over a step of h.

    held: F_port, F_stbd [N], measured and commanded angles [rad], exp(A h), the rate limit
    [rad/s] and the step's largest move [rad], the loop gain k1 / k2 [1/s], the motor's lag
    over the step exp(-k2 h), h [s], (1 - exp(-k2 h)) / k2 [s], 1 for a drive (0: none).
    """
    f_port = thrust(p, cmd[0]) * p[_SP]
    f_stbd = thrust(p, cmd[1]) * p[_SS]
    k1 = p[_K1]
    k2 = p[_K2]
    if k1 > 0.0:
        p11, p12, p21, p22, lag = transition(k1, k2, h)
    else:   # no dynamics: the angle follows its command at once
        p11, p12, p21, p22, lag = 0.0, 0.0, 0.0, 0.0, 1.0
    rmax = p[_RMAX]
    if rmax > 0.0 and k1 > 0.0 and k2 > 0.0:   # the slewing motor's lag, for a saturated loop
        gain = k1 / k2
        lead = (1.0 - lag) / k2
    else:
        gain, lead = 0.0, h
    return OK, (f_port, f_stbd, cmd[2], cmd[3], cmd[4], cmd[5], p11, p12, p21, p22, rmax,
                rmax * h, gain, lag, h, lead, 1.0 if k1 > 0.0 else 0.0)


@njit(cache=True, fastmath=FASTMATH, inline='always')
def _follow(a: FloatArray, i: int, measured: float, cmd: float, held: tuple[float, ...]) -> float:
    """
    Advance one thruster's (angle, rate) at a[i], a[i + 1]; return the angle acting over the step.

    The angle acting over a step is the mean of its start and end (the end alone led the
    drive by half a step: a fit at 0.1 s steps read k1 15 % low). Unsaturated, the drive is
    eq. 9, integrated exactly. With a rate limit the position loop asks the slewing motor for
    the rate (k1 / k2) (alpha_c - alpha); where that exceeds the limit the motor is asked for
    the limit and its rate approaches it with the drive's lag 1 / k2 (exact for the step; the
    regime is decided at the step's start). A drive is limited in the speed it can be asked
    for, not in a rate that jumps to the limit.
    """
    if cmd != cmd:   # no command recorded: the measured angle acts
        a[i] = measured
        a[i + 1] = 0.0
        return measured
    e = a[i] - cmd
    w = a[i + 1]
    rmax = held[10]
    if rmax > 0.0 and abs(held[12] * e) > rmax:
        s = -rmax if e > 0.0 else rmax
        rate = s + (w - s) * held[13]
        new = a[i] + s * held[14] + (w - s) * held[15]
        if (new - cmd) * e < 0.0:   # a step longer than the slew left: stop at the command
            new = cmd
    else:
        new = cmd + held[6] * e + held[7] * w
        rate = held[8] * e + held[9] * w
    if rmax > 0.0:   # neither the rate nor the step's move exceeds the limit
        if rate > rmax:
            rate = rmax
        elif rate < -rmax:
            rate = -rmax
        move = new - a[i]
        if move > held[11]:
            new = a[i] + held[11]
        elif move < -held[11]:
            new = a[i] - held[11]
    old = a[i]
    a[i] = new
    a[i + 1] = rate
    if held[16] == 0.0:   # no drive: the command acts at once
        return new
    return 0.5 * (old + new)


@njit(cache=True, fastmath=FASTMATH, inline='always')
def output(p: FloatArray, held: tuple[float, ...], a: FloatArray,
           i: int) -> tuple[float, float, float, float]:
    """Advance both angles over one step; return (F_port, F_stbd, alpha_port, alpha_stbd)."""
    ap = _follow(a, i, held[2], held[4], held)
    ast = _follow(a, i + 2, held[3], held[5], held)
    return (held[0], held[1], ap + p[_OP], ast + p[_OS])


@njit(cache=True, fastmath=FASTMATH, inline='always')
def forces(p: FloatArray, u: float, v: float, r: float, act: tuple[float, ...],
           k: int) -> tuple[float, float, float]:
    """Return tau = T(alpha) f (eq. 8): (X [N], Y [N], N [N m]) about the reference point."""
    fp = act[k]
    fs = act[k + 1]
    cp = math.cos(act[k + 2])
    sp = math.sin(act[k + 2])
    cs = math.cos(act[k + 3])
    ss = math.sin(act[k + 3])
    X = fp * cp + fs * cs
    Y = fp * sp + fs * ss
    N = (fp * (p[_XP] * sp - p[_YP] * cp) + fs * (p[_XS] * ss - p[_YS] * cs))
    return X, Y, N
