"""
The control-oriented Esso Osaka model (issue 24 on real data): actuator, config, local step.

``screw_rudder_tau`` (propeller and rudder as tau, linear in 7 coefficients), the family
``surge_decoupled_rudder`` and ``config/esso_osaka_3m_control.yaml``, identified by the local
step on a real pond run.
"""
from pathlib import Path

import mmg_tuner as mt
from mmg_tuner.core.actuators import actuator
from mmg_tuner.data.esso import read_esso_csv
from mmg_tuner.data.trial import Trial
from mmg_tuner.tuning.lo_go import equation_error, interval_data, lo_fit
import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[2]
ZIGZAG = ROOT / 'data' / 'esso_osaka_frt' / 'zigzag' / 'zigzag_31-Jul-2020_13_04_24.csv'
ACTUATOR_COEFFICIENTS = ('T_nn', 'T_absn_u', 'X_uudd', 'Y_uud', 'Y_nnd', 'N_uud', 'N_nnd')


@pytest.fixture(scope='module')
def ship():
    return mt.load_ship('esso_osaka_3m_control')


def tau(ship, u, n_rps, delta):
    """Return the actuator's (X, Y, N) at surge speed u [m/s], n [rev/s], rudder delta [rad]."""
    return actuator('screw_rudder_tau').forces(ship.params, u, 0.0, 0.0, (n_rps, delta), 0)


def test_config_loads_with_the_actuator_and_its_targets(ship):
    assert ship.model == 'surge_decoupled_rudder'
    assert ship.family.actuators == ('screw_rudder_tau', 'tunnel_thrusters')
    assert ship.family.channels[:2] == ('rpm', 'rudder')
    assert set(ACTUATOR_COEFFICIENTS) <= set(ship.tuning_targets)
    # the mass matrix stays at the published values: it fixes the scale of the local step
    assert not {'m11', 'm22', 'm23', 'm32', 'm33'} & set(ship.tuning_targets)
    assert ship['m11'] == pytest.approx(244.6009 + 0.0467 * 0.5 * 998 * 9 * 0.20114, rel=1e-4)


def test_thrust_is_ahead_at_positive_revolutions_and_astern_at_negative(ship):
    X, Y, N = tau(ship, 0.0, 10.0, 0.0)
    assert X == pytest.approx(ship['T_nn'] * 100.0) and X > 0 and Y == 0 and N == 0
    assert tau(ship, 0.0, -10.0, 0.0)[0] == pytest.approx(-X)
    # the speed term: less thrust at speed ahead (the advance ratio), as K_T(J) falls
    assert tau(ship, 0.5, 10.0, 0.0)[0] < X


def test_positive_rudder_turns_to_starboard(ship):
    # conventions.md: rudder + = starboard helm; the rudder aft pushes the stern to port
    for u, n in ((0.5, 8.0), (0.0, 8.0), (0.5, 0.0)):
        X, Y, N = tau(ship, u, n, np.radians(20.0))
        assert Y < 0 < N, (u, n, Y, N)
        assert X < tau(ship, u, n, 0.0)[0] or u == 0.0   # rudder drag (u^2 delta^2)
        Xm, Ym, Nm = tau(ship, u, n, np.radians(-20.0))
        assert (Ym, Nm) == pytest.approx((-Y, -N))
    # astern revolutions blow no slipstream onto the rudder
    assert tau(ship, 0.0, -8.0, 0.3)[1:] == (0.0, 0.0)


def test_simulates_and_turns_to_starboard_with_starboard_helm(ship):
    t = np.arange(0.0, 30.0, 0.5)
    states = np.zeros((len(t), 6))
    states[:, 0] = 0.4 * t    # straight ahead at 0.4 m/s: the start state the fit finds
    states[:, 3] = 0.4
    inputs = {'rpm': np.full(len(t), 600.0), 'rudder': np.full(len(t), np.radians(20.0))}
    run = mt.simulate(ship, Trial(t, states, name='starboard helm', inputs=inputs))
    assert np.all(np.isfinite(run.states))
    assert run.states[-1, 5] > 0.01    # r [rad/s]: clockwise, to starboard
    assert run.states[-1, 1] > 0.5     # y east: the ship went to starboard of its track


def test_lo_on_a_short_real_run_reproduces_its_accelerations(ship):
    tr = read_esso_csv(ZIGZAG, keep_astern=True)[0]
    assert 100.0 < tr.duration_s < 200.0 and tr.dt == pytest.approx(0.1)
    lo = lo_fit(ship, [tr])
    assert lo.names == ship.tuning_targets
    fitted = ship.with_params(dict(zip(lo.names, lo.theta)))
    zero = ship.with_params(dict.fromkeys(lo.names, 0.0))
    data = interval_data(ship, tr, 2.0)
    e_lo = np.sqrt(np.mean(equation_error(fitted, fitted.params, data) ** 2, axis=0))
    e_0 = np.sqrt(np.mean(equation_error(zero, zero.params, data) ** 2, axis=0))
    # the one-step equation error [N, N, N m] of every DOF clearly below that of no
    # coefficients (measured: 0.70, 0.40, 0.30 of it; surge is mostly steady on a zigzag)
    assert np.all(e_lo < np.array([0.85, 0.6, 0.5]) * e_0), (e_lo, e_0)
    assert lo.residual_rms == pytest.approx(tuple(e_lo), rel=1e-6)


def test_lo_refuses_a_scale_it_cannot_determine(ship):
    tr = read_esso_csv(ZIGZAG, keep_astern=True)[0]
    every = ('m11', 'm22', 'm23', 'm32', 'm33') + ship.tuning_targets
    with pytest.raises(mt.TuningError, match='homogeneous'):
        lo_fit(ship, [tr], every)


def test_nstep_scores_a_network_restarted_from_every_measured_state(ship):
    from mmg_tuner.learn.residual import zero_net
    from mmg_tuner.tuning.nstep import nstep_errors
    tr = read_esso_csv(ZIGZAG, keep_astern=True)[0].resampled(0.5)
    tr = tr.slice(tr.t[0], tr.t[0] + 60.0)
    hs = (1, 4, 20)
    physics, _ = nstep_errors(ship, [tr], hs)
    hybrid, _ = nstep_errors(mt.Model(ship, zero_net(5, 0.5)), [tr], hs)
    for s in ('u', 'v', 'r', 'x', 'y', 'psi'):   # a zero residual: the physics, window by window
        assert hybrid.rmse[s] == pytest.approx(physics.rmse[s], rel=1e-9, abs=1e-12), s
    # a pure network predicting no acceleration holds the measured velocities of sample k
    coast, _ = nstep_errors(mt.Model(ship, zero_net(5, 0.5, physics=False)), [tr], hs)
    for i, h in enumerate(hs):
        for j, s in ((3, 'u'), (4, 'v'), (5, 'r')):
            d = tr.states[h:, j] - tr.states[:-h, j]
            assert coast.rmse[s][i] == pytest.approx(np.sqrt(np.mean(d ** 2)), rel=1e-9), (s, h)
    with pytest.raises(mt.TuningError, match='resample'):
        nstep_errors(mt.Model(ship, zero_net(5, 0.2)), [tr], hs)
