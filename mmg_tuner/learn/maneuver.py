"""
Manoeuvres of a ship that carries a residual network (hybrid or pure network).

No command drives the compiled step itself: the open-loop programmes replay the physics run's
inputs through ``simulate_hybrid_one``; the zigzag closes the loop on the hybrid's own heading
through ``steer_hybrid_one``; both are the core's one sample loop (``integrate.drive``) with the
network attached.
"""
from __future__ import annotations

import math
from typing import Any, cast

from mmg_tuner.core import maneuvers as mv
from mmg_tuner.core.dynamics import family_tag
from mmg_tuner.core.layout import OK, STATUS_TEXT
from mmg_tuner.core.simulate import integrator_code
from mmg_tuner.core.trial import input_array, Trial
from mmg_tuner.learn.model import Model
from mmg_tuner.learn.residual import ResidualNet, simulate_hybrid_one, steer_hybrid_one
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
    # (called for a model that carries a network: its residual is set)
    ship, net = model.ship, cast(ResidualNet, model.residual)
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
        np.zeros((max(1, net.window - 1), net.n_features)), 0, ctrl, T, float(spec.dt),
        int(spec.substeps), integrator_code(spec.integrator), int(net.window), sizes, flat,
        net.x_mean, net.x_std, net.y_scale, float(net.physics), out, res)
    kw: dict[str, Any] = {} if status == OK else {
        'status': STATUS_TEXT[status], 'fail_time_s': float(phys.t[min(k_fail, T - 1)])}
    return Trial(phys.t.copy(), out, name=spec.maneuver, inputs=phys.inputs, **kw)


def _hybrid_zigzag(model: Model, spec: mv.ManeuverSpec, phys: Trial) -> Trial:
    """Return the IMO zigzag of integrate.run_maneuver, closed on the hybrid's heading."""
    ship, net = model.ship, cast(ResidualNet, model.residual)   # (as hybrid_maneuver's)
    T = len(phys)
    amp = math.radians(spec.rudder_deg)
    check = math.radians(abs(spec.check_deg if spec.check_deg is not None
                             else spec.rudder_deg))
    rate = ship.rudder_rate_rad_s if spec.rudder_rate_deg_s is None \
        else math.radians(spec.rudder_rate_deg_s)
    rpm = phys['rpm']
    orders = np.where(phys.t >= spec.approach_s, amp, 0.0)   # as mv.run orders a zigzag
    channels = ship.family.channels
    ctrl = input_array(channels, {'rpm': rpm, 'rudder': orders}, T, spec.maneuver)
    gear = np.array([float(channels.index('rudder')), amp, check, rate])
    x0 = np.array([0.0, 0.0, 0.0, spec.speed_ms, 0.0, 0.0])   # mv.run's start (midship)
    out = np.empty((T, 6))
    rudder = np.empty(T)
    res = np.empty((T, 3))
    sizes, flat = net.packed()
    status, k_fail = steer_hybrid_one(
        family_tag(ship.kind), np.ascontiguousarray(ship.params, dtype=float), x0, ctrl, gear,
        T, float(spec.dt), int(spec.substeps), integrator_code(spec.integrator),
        int(net.window), sizes, flat, net.x_mean, net.x_std, net.y_scale, float(net.physics),
        out, rudder, res)
    kw: dict[str, Any] = {} if status == OK else {
        'status': STATUS_TEXT[status], 'fail_time_s': float(phys.t[min(k_fail, T - 1)])}
    return Trial(phys.t.copy(), out, np.column_stack([rpm, rudder]), name=spec.maneuver, **kw)
