"""
Manoeuvres of a ship that carries a residual network (hybrid or pure network).

Moved from the ``simulate`` command so that no command drives the compiled step itself: the
open-loop programmes replay the physics run's inputs through ``simulate_hybrid_one``; the
zigzag closes the loop on the hybrid's own heading through the core's ``advance``.
"""
from __future__ import annotations

import math

from mmg_tuner.core import maneuvers as mv
from mmg_tuner.core.dynamics import family_tag, N_ACT_STATES
from mmg_tuner.core.integrate import advance, observe, start_actuators, start_state
from mmg_tuner.core.layout import OK, STATUS_TEXT
from mmg_tuner.core.simulate import integrator_code
from mmg_tuner.core.stepper import apparent_wind_body
from mmg_tuner.core.trial import Trial
from mmg_tuner.learn.model import Model
from mmg_tuner.learn.residual import N_FEATURES, simulate_hybrid_one
import numpy as np


def hybrid_maneuver(model: Model, spec: mv.ManeuverSpec) -> Trial:
    """
    One manoeuvre of a ship that carries a residual network (hybrid or pure network).

    The programme's inputs come from the physics run (mv.run): open-loop manoeuvres (turning,
    pull-out, random, the low-speed programmes, whose phase ends the physics decides) replay
    its rpm, actual rudder angle and thrusters through the hybrid from the same first state,
    as a recorded trial is replayed; a zigzag closes the loop on the hybrid's own heading,
    step by step (the residual held over each sample, the steering gear per substep).
    """
    ship, net = model.ship, model.residual
    phys = mv.run(ship, spec)
    if spec.maneuver == 'zigzag':
        return _hybrid_zigzag(model, spec, phys)
    ctrl = np.ascontiguousarray(phys.input_array(ship.family.channels))
    if not phys.ok:   # past the physics' failure the programme is undefined: hold its last
        n_cmd = len(ship.family.inputs)
        k = max(1, int(np.argmax(~np.all(np.isfinite(ctrl[:, :n_cmd]), axis=1))))
        ctrl[k:] = ctrl[k - 1]
    T = len(phys)
    out = np.empty((T, 6))
    res = np.empty((T, 3))
    sizes, flat = net.packed()
    status, k_fail = simulate_hybrid_one(
        family_tag(ship.kind), np.ascontiguousarray(ship.params, dtype=float),
        phys.states[0].copy(),
        np.zeros((max(1, net.window - 1), N_FEATURES)), 0, ctrl, T, float(spec.dt),
        int(spec.substeps), integrator_code(spec.integrator), int(net.window), sizes, flat,
        net.x_mean, net.x_std, net.y_scale, float(net.physics), out, res)
    kw = {} if status == OK else {'status': STATUS_TEXT[status],
                                  'fail_time_s': float(phys.t[min(k_fail, T - 1)])}
    return Trial(phys.t.copy(), out, name=spec.maneuver, inputs=phys.inputs, **kw)


def _hybrid_zigzag(model: Model, spec: mv.ManeuverSpec, phys: Trial) -> Trial:
    """Return the IMO zigzag of integrate.run_maneuver, closed on the hybrid's heading."""
    ship, net = model.ship, model.residual
    tag = family_tag(ship.kind)
    p = np.ascontiguousarray(ship.params, dtype=float)
    T, dt, n_sub = len(phys), float(spec.dt), int(spec.substeps)
    h = dt / n_sub
    amp = math.radians(spec.rudder_deg)
    check = math.radians(abs(spec.check_deg if spec.check_deg is not None
                             else spec.rudder_deg))
    rate = ship.rudder_rate_rad_s if spec.rudder_rate_deg_s is None \
        else math.radians(spec.rudder_rate_deg_s)
    max_move = rate * h if rate > 0 else math.inf
    rpm = phys['rpm']
    method = integrator_code(spec.integrator)
    s = np.empty(6)
    start_state(p, phys.states[0].copy(), s)
    out = np.full((T, 6), np.nan)
    rudder = np.full(T, np.nan)
    observe(p, s, out[0])
    delta = 0.0
    rudder[0] = delta
    # one sample of the input array: rpm, rudder (the logged angle), thrusters 0, no wind
    row = np.full((1, len(ship.family.channels)), np.nan)
    row[0, :len(ship.family.inputs)] = 0.0
    act_states = np.zeros(N_ACT_STATES)
    start_actuators(tag, p, row, 0.0, 1, act_states)
    started, cmd_zz, psi0 = False, amp, s[2]
    stepper = net.stepper()
    status, k_fail = OK, T
    for k in range(T - 1):
        a0, a1, a2 = stepper.accelerations(s, (rpm[k], delta), apparent_wind_body(ship, s))
        for _ in range(n_sub):
            if not started and phys.t[k] >= spec.approach_s:
                started, psi0 = True, s[2]
            cmd = 0.0
            if started:
                if cmd_zz > 0 and s[2] - psi0 >= check:
                    cmd_zz = -abs(amp)
                elif cmd_zz < 0 and s[2] - psi0 <= -check:
                    cmd_zz = abs(amp)
                cmd = cmd_zz
            row[0, 0], row[0, 1] = rpm[k], delta
            status = advance(tag, p, s, act_states, row, 0, 0.0, 1, h, 1, method, a0, a1, a2,
                             float(net.physics))
            if status != OK:
                break
            delta += min(max_move, max(-max_move, cmd - delta))
        if status != OK:
            k_fail = k + 1
            break
        observe(p, s, out[k + 1])
        rudder[k + 1] = delta
    kw = {} if status == OK else {'status': STATUS_TEXT[status],
                                  'fail_time_s': float(phys.t[min(k_fail, T - 1)])}
    return Trial(phys.t.copy(), out, np.column_stack([rpm, rudder]), name=spec.maneuver, **kw)
