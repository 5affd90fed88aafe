"""The MMG core: the paper's check, physics sanity, batching, integrators, range checks."""
import math

from mmg_tuner.core import indices as ix
from mmg_tuner.core import maneuvers as mv
from mmg_tuner.core.layout import PARAM_INDEX
from mmg_tuner.core.simulate import self_propulsion_rpm, simulate, simulate_batch
from mmg_tuner.errors import SimulationError
import numpy as np
import pytest

KN6 = 6 * mv.KNOT


def paper_turn(ship, rudder_deg):
    spec = mv.ManeuverSpec('turning', rudder_deg=rudder_deg, rpm=106.0, speed_ms=KN6,
                           duration_s=900.0, dt=1.0, rudder_rate_deg_s=0.0)
    traj = mv.run(ship, spec)
    assert traj.ok
    return ix.turning_indices(traj['x'], traj['y'], traj['psi'])


def test_paper_check_starboard_circle_larger(suzaku):
    """
    Suyama et al. 2023 Fig. 3: the starboard turning circle is larger than the port one.

    Suyama et al. 2023 sec. 6.1 / Fig. 3: Euler dt = 1 s, 6 kn, 106 rpm, delta = +-35 deg: the
    starboard turning circle is larger than the port one.
    """
    stbd, port = paper_turn(suzaku, 35.0), paper_turn(suzaku, -35.0)
    assert stbd.direction == 'starboard' and port.direction == 'port'
    assert stbd.tactical_diameter_m > 1.1 * port.tactical_diameter_m
    assert stbd.advance_m > port.advance_m
    for ti in (stbd, port):  # a container ship at 35 deg turns in roughly 2-3 lengths
        assert 1.5 < ti.tactical_diameter_m / suzaku.L_pp < 3.5


def test_straight_run_settles_and_holds_self_propulsion_speed(suzaku, kvlcc2):
    for ship, speed in ((suzaku, KN6), (kvlcc2, 1.179)):
        rpm = self_propulsion_rpm(ship, speed)
        T = 3001
        traj = simulate(ship, [0, 0, 0, speed, 0, 0], np.tile([rpm, 0.0], (T, 1)), dt=0.5)
        assert traj.ok
        assert abs(traj['u'][-1] - speed) < 1e-3 * speed
        # away from it, the speed settles to a new steady value
        traj = simulate(ship, [0, 0, 0, 0.7 * speed, 0, 0], np.tile([rpm, 0.0], (T, 1)), dt=0.5)
        assert abs(traj['u'][-1] - traj['u'][-41]) < 1e-3 * speed
        assert abs(traj['u'][-1] - speed) < 0.01 * speed
        if ship.model == 'standard':  # no propeller side force: a straight track
            assert np.allclose(traj['v'], 0) and np.allclose(traj['r'], 0)
        else:  # the paper's propeller side force (C_PY, C_PN) makes a slow steady turn
            assert abs(traj['r'][-1] - traj['r'][-41]) < 1e-6 and abs(traj['v'][-1]) < 0.01


def test_batched_equals_single(suzaku):
    rng = np.random.default_rng(1)
    T = 300
    ctrls = np.stack([np.column_stack([np.full(T, 100 + 10 * j),
                                       np.radians(20) * np.sin(np.arange(T) / (20 + 10 * j))])
                      for j in range(3)])
    x0s = np.array([[0, 0, 0, 3.0, 0, 0], [10, 5, 0.3, 2.5, 0.1, 0.01], [0, 0, -1, 3.5, 0, 0]])
    params = np.tile(suzaku.params, (4, 1))
    params[:, PARAM_INDEX['t_P']] *= rng.uniform(0.6, 1.4, 4)
    params[:, PARAM_INDEX['gamma_Rn']] *= rng.uniform(0.6, 1.4, 4)
    lengths = np.array([T, T - 50, T - 120])
    for integ in ('euler', 'rk4'):
        out, status, _ = simulate_batch(suzaku.kind, params, x0s, ctrls, 1.0, lengths, integ, 2)
        assert (status == 0).all()
        for i in range(4):
            for j in range(3):
                single = simulate(suzaku, x0s[j], ctrls[j, :lengths[j]], 1.0, integ, 2,
                                  params=params[i])
                # same kernel; LLVM may contract the inlined step differently inside the
                # parallel loop (fast-math 'contract'): equal to rounding, not bit for bit
                np.testing.assert_allclose(out[i, j, :lengths[j]], single.states,
                                           rtol=1e-12, atol=1e-12)
    assert not np.allclose(out[0, 0], out[1, 0])  # the candidates really differ


def test_euler_and_rk4_converge_to_each_other(suzaku):
    T_end = 200.0
    x0 = [0, 0, 0, KN6, 0, 0]

    def final(dt, integ):
        n = int(round(T_end / dt)) + 1
        ctrl = np.tile([106.0, math.radians(20)], (n, 1))
        return simulate(suzaku, x0, ctrl, dt, integ).states[-1]

    ref = final(0.01, 'rk4')
    err_euler = [np.abs(final(dt, 'euler') - ref)[:2].max() for dt in (1.0, 0.5, 0.25)]
    err_rk4 = [np.abs(final(dt, 'rk4') - ref)[:2].max() for dt in (1.0, 0.5)]
    # Euler is first order: halving dt roughly halves the error; RK4 is far more accurate
    assert 1.6 < err_euler[0] / err_euler[1] < 2.5
    assert 1.6 < err_euler[1] / err_euler[2] < 2.5
    assert err_rk4[0] < err_euler[0] / 50
    assert err_rk4[0] / max(err_rk4[1], 1e-12) > 8  # ~16 for a fourth-order method


def test_negative_rpm_is_refused_with_time(suzaku):
    ctrl = np.tile([106.0, 0.0], (20, 1))
    ctrl[7, 0] = -50.0
    with pytest.raises(SimulationError, match=r'rpm = -50.00 at t = 7.00 s'):
        simulate(suzaku, [0, 0, 0, 3.0, 0, 0], ctrl, 1.0)
    with pytest.raises(SimulationError, match='u > 0'):
        simulate(suzaku, [0, 0, 0, -1.0, 0, 0], np.tile([106.0, 0.0], (5, 1)), 1.0)
    ctrl = np.tile([106.0, 0.0], (20, 1))
    ctrl[3, 1] = np.nan
    with pytest.raises(SimulationError, match='non-finite control at t = 3.00 s'):
        simulate(suzaku, [0, 0, 0, 3.0, 0, 0], ctrl, 1.0)


def test_stopping_ship_is_reported_not_nan(suzaku):
    ship = suzaku.with_params({'R_0': 50.0})  # absurd resistance: Euler stops the ship dead
    traj = simulate(ship, [0, 0, 0, 3.0, 0, 0], np.tile([20.0, 0.0], (600, 1)), 1.0)
    assert not traj.ok and 'u <= 0' in traj.status
    k = int(round(traj.fail_time_s))
    assert np.all(np.isfinite(traj.states[:k])) and np.all(np.isnan(traj.states[k:]))


def test_diverging_simulation_is_reported(suzaku):
    ship = suzaku.with_params({'N_r': 400.0, 'Y_v': 300.0})  # unstable hull: blows up
    traj = simulate(ship, [0, 0, 0, 3.0, 0.1, 0.01], np.tile([106.0, 0.3], (2000, 1)), 1.0)
    assert not traj.ok
    assert traj.status.startswith(('diverged', 'surge'))
    out, status, k_fail = simulate_batch(ship.kind, np.stack([suzaku.params, ship.params]),
                                         np.array([[0, 0, 0, 3.0, 0.1, 0.01]]),
                                         np.tile([106.0, 0.3], (1, 2000, 1)), 1.0)
    assert status[0, 0] == 0 and status[1, 0] != 0 and k_fail[1, 0] < 2000


def test_rudder_rate_limit_and_zigzag_reversal(suzaku):
    spec = mv.ManeuverSpec('zigzag', rudder_deg=20, rpm=106, speed_ms=KN6, duration_s=600,
                           dt=0.5)
    traj = mv.run(suzaku, spec)
    rate = np.abs(np.diff(traj['rudder'])) / 0.5
    assert rate.max() <= suzaku.rudder_rate_rad_s * (1 + 1e-9)
    assert rate.max() > 0.9 * suzaku.rudder_rate_rad_s
    # the rudder starts moving to port right after the heading passes +20 deg
    dpsi = np.degrees(traj['psi'] - traj['psi'][0])
    k_cross = int(np.argmax(dpsi >= 20.0))
    assert traj['rudder'][k_cross - 1] == pytest.approx(math.radians(20))
    assert traj['rudder'][k_cross + 1] < math.radians(20)
    zz = ix.zigzag_indices(traj['psi'], traj['rudder'], math.radians(20))
    assert zz.direction == 'starboard' and 0 < zz.first_overshoot_deg < 30
    assert 0 < zz.second_overshoot_deg < 40


def test_pullout_and_random(suzaku):
    pull = mv.run(suzaku, mv.ManeuverSpec('pullout', rudder_deg=20, rpm=106, speed_ms=KN6,
                                          duration_s=900, pullout_s=300))
    assert pull.ok and pull['rudder'][-1] == 0.0 and abs(pull['r'][-1]) < abs(pull['r'][299])
    a = mv.run(suzaku, mv.ManeuverSpec('random', rudder_deg=30, duration_s=600, seed=3,
                                       random_rpm_frac=0.1))
    b = mv.run(suzaku, mv.ManeuverSpec('random', rudder_deg=30, duration_s=600, seed=3,
                                       random_rpm_frac=0.1))
    c = mv.run(suzaku, mv.ManeuverSpec('random', rudder_deg=30, duration_s=600, seed=4))
    np.testing.assert_array_equal(a.states, b.states)
    assert not np.allclose(a.states, c.states)
    assert np.ptp(a['rpm']) > 5 and np.abs(a['rudder']).max() <= math.radians(30) + 1e-12


def test_indices_on_a_perfect_circle():
    R = 100.0
    th = np.linspace(0, 1.5 * np.pi, 2000)  # starboard turn from heading north at (0, 0)
    x, y, psi = R * np.sin(th), R * (1 - np.cos(th)), th
    ti = ix.turning_indices(x, y, psi)
    assert ti.direction == 'starboard'
    assert ti.advance_m == pytest.approx(R, rel=1e-4)
    assert ti.transfer_m == pytest.approx(R, rel=1e-4)
    assert ti.tactical_diameter_m == pytest.approx(2 * R, rel=1e-4)
    ti = ix.turning_indices(x, -y, -psi)
    assert ti.direction == 'port' and ti.tactical_diameter_m == pytest.approx(2 * R, rel=1e-4)


@pytest.mark.parametrize('effect', [
    {'current_speed': 0.4, 'current_dir': 1.2}, {'rudder_offset': math.radians(2.0)},
    {'rudder_lag_tau': 5.0}, {'rpm_scale': 0.95}, {'yaw_moment_bias': 0.002},
    {'antenna_x': 20.0, 'antenna_y': -3.0}, {'wind_speed': 12.0, 'wind_dir': -0.7},
    {'prop_side_force': 0.01}])
def test_effects_generated_and_replayed_consistently(suzaku, effect):
    """
    A manoeuvre generated with an effect replays exactly through the simulator.

    Given the same effect, and visibly differs without it.
    """
    ship = suzaku.with_params(effect)
    spec = mv.ManeuverSpec('zigzag', rudder_deg=20, rpm=106, speed_ms=KN6, duration_s=300)
    gen = mv.run(ship, spec)
    replay = simulate(ship, gen.states[0], gen.controls, 1.0)
    np.testing.assert_allclose(replay.states, gen.states, atol=1e-8)
    base = simulate(suzaku, gen.states[0], gen.controls, 1.0)
    assert np.abs(base.states[:, :2] - gen.states[:, :2]).max() > 1.0


def test_wind_loads_act_the_way_a_seaman_expects(suzaku):
    """
    Blendermann loads, heading north at 3 m/s.

    A head wind slows the ship, a beam wind pushes it to leeward, and on a ship at rest, with the
    windage centroid aft (s_L < 0), a beam wind turns the bow into it; port and starboard winds
    mirror each other.
    """
    from mmg_tuner.core.dynamics import wind_loads

    def loads(wind_from_deg, u=3.0):
        p = suzaku.with_params({'wind_speed': 10.0, 'wind_dir': math.radians(wind_from_deg)})
        return wind_loads(p.params, 0.0, u, 0.0)

    X, Y, N = loads(0.0)
    assert X < 0 and abs(Y) < 1e-6 * abs(X) and abs(N) < 1e-6 * abs(X)
    head = X
    X, Y, N = loads(90.0, u=0.0)        # from starboard, at rest
    assert Y < 0 and N > 0              # pushed to port, bow to starboard (into the wind)
    assert N == pytest.approx(Y * suzaku['s_L'])
    X, Y, N = loads(90.0)               # under way the apparent wind comes from forward of
    assert Y < 0 and N < 0              # the beam: the centre of effort moves forward
    Xp, Yp, Np = loads(-90.0)           # from port: the mirror image
    assert (Xp, Yp, Np) == pytest.approx((X, -Y, -N))
    X, _, _ = loads(180.0)              # from astern, less than the head wind's 8 m/s more
    assert 0 < X < -head
    # the apparent wind speed counts: 10 m/s from ahead at 3 m/s ahead = 13 m/s apparent
    q = 0.5 * suzaku['rho_air'] * 13.0 ** 2
    assert head == pytest.approx(-suzaku['CD_lAF_bow'] * q * suzaku['A_F'])


def test_measured_wind_replaces_the_wind_parameters(suzaku):
    """
    The kernels read a measured wind from two extra input channels (north/east air velocity).

    A steady measured wind replays exactly what the wind parameters generate.
    """
    ship = suzaku.with_params({'wind_speed': 12.0, 'wind_dir': 1.0})
    gen = mv.run(ship, mv.ManeuverSpec('zigzag', rudder_deg=20, rpm=106, speed_ms=KN6,
                                       duration_s=200))
    to = 1.0 + math.pi
    wind = np.tile([12.0 * math.cos(to), 12.0 * math.sin(to)], (len(gen.t), 1))
    measured = simulate(suzaku, gen.states[0], np.column_stack([gen.controls, wind]), 1.0)
    np.testing.assert_allclose(measured.states, gen.states, atol=1e-8)
    nan_wind = simulate(ship, gen.states[0], np.column_stack([gen.controls, wind * np.nan]), 1.0)
    np.testing.assert_allclose(nan_wind.states, gen.states, atol=1e-8)  # NaN: parameters
    with pytest.raises(SimulationError, match='controls must be'):
        simulate(suzaku, gen.states[0], gen.controls[:, :1], 1.0)
