"""
The interactive simulator never dies or lies.

Plausibility ranges from the ship, bad commands ignored or clamped, bad settings refused, and any
non-finite or implausible state reset with a diagnostic (issue 10 section 2). Unit level, no ROS.
"""
import math

from hypothesis import given, HealthCheck, settings
from hypothesis import strategies as st
from mmg_tuner.core.limits import input_limits
from mmg_tuner.core.simulate import self_propulsion_rpm, simulate
from mmg_tuner.core.stepper import ShipSimulator
from mmg_tuner.errors import SimulationError
import numpy as np
import pytest

NASTY = [math.nan, math.inf, -math.inf, 1e308, -1e308, 1e6, 1e4, -50.0, 0.0, -0.0, 5e-324]


@pytest.fixture(scope='module')
def sim(suzaku):
    return ShipSimulator(suzaku, dt=0.1, x0=[0, 0, 0, 3.0, 0, 0], rpm=106.0)


def plausible(sim) -> bool:
    s = sim.s
    lim = sim.limits
    return bool(np.all(np.isfinite(s)) and math.hypot(s[3], s[4]) <= lim.speed_max_ms
                and abs(s[5]) <= lim.yaw_rate_max_rad_s)


def test_limits_are_physical_and_consistent(suzaku, kvlcc2):
    for ship, service_rpm in ((suzaku, 106.0), (kvlcc2, 706.0)):
        lim = input_limits(ship)
        assert lim is input_limits(ship)  # cached
        # a generous multiple of the service rpm, far below a unit error (rad/s or rev/s)
        rpm, rudder = lim.channels['rpm'], lim.channels['rudder']
        assert 3 * service_rpm < rpm.limit < 20 * service_rpm
        assert rpm.limit == pytest.approx(2 * self_propulsion_rpm(ship, lim.top_speed_ms))
        assert rpm.forward_only and rpm.plausible == rpm.recorded == rpm.limit
        assert rudder.limit == ship.max_rudder_rad
        assert rudder.limit < rudder.plausible == rudder.recorded <= math.pi / 2
        froude = lim.top_speed_ms / math.sqrt(9.80665 * ship.L_pp)
        assert froude == pytest.approx(0.5)
        assert lim.dt_min_s <= 0.1 <= lim.dt_max_s
        # the largest accepted command held in a straight run never looks like divergence
        # (steady speed about Fn 1.0 against the Fn 1.5 cap: no knife-edge)
        T = 2001
        traj = simulate(ship, [0, 0, 0, 1.0, 0, 0], np.tile([rpm.limit, 0.0], (T, 1)), 0.5,
                        'rk4')
        speed = np.hypot(traj['u'], traj['v'])
        assert traj.ok and np.all(np.isfinite(speed)) and speed.max() < 0.8 * lim.speed_max_ms
        assert rpm.problem(rpm.limit) == '' and rpm.problem(2 * rpm.limit)
        assert rudder.problem(1e308) and rudder.problem(math.nan)
        assert 'clamped' in rudder.check(2 * rudder.limit - 1e-9)[1]


def test_huge_rpm_commands_never_give_a_nan_state(suzaku):
    """Rudder 0.3 with rpm 1e4, then 1e6: the state went NaN and step() said success."""
    sim = ShipSimulator(suzaku, dt=0.1, x0=[0, 0, 0, 3.0, 0, 0], rpm=106.0)
    assert sim.set_rudder(0.3) == ''
    assert 'ignored' in sim.set_rpm(1e4)
    assert sim.step(250)
    assert 'ignored' in sim.set_rpm(1e6)
    assert 'ignored' in sim.set_rpm(1e308)
    assert sim.step(250)
    assert sim.rpm == 106.0 and plausible(sim)


def test_a_non_finite_state_is_detected_and_reset(suzaku):
    """
    advance()'s own isfinite(sum) check is folded away under fastmath.

    A NaN must still be caught, even in x (which feeds no derivative).
    """
    sim = ShipSimulator(suzaku, dt=0.1, x0=[5.0, 0, 0, 3.0, 0, 0], rpm=106.0)
    sim.set_rudder(0.2)
    assert sim.step(30)
    sim.s[0] = math.nan
    assert not sim.step(10)
    f = sim.failure
    assert f is not None and 'non-finite' in f.reason and f.time_s == pytest.approx(3.1)
    assert f.rpm == 106.0 and f.rudder_rad == 0.2
    assert 'rpm 106' in str(f) and 'rudder 11.46 deg' in str(f) and 'last good state' in str(f)
    # back at the initial state and commands, and running again
    assert sim.t == 0.0 and sim.rudder == 0.0 and np.all(np.isfinite(sim.s))
    assert sim.s[0] == pytest.approx(5.0) and sim.failures == 1
    assert sim.step(10) and plausible(sim)


def test_divergence_within_the_limits_resets_with_a_diagnostic(kvlcc2):
    """
    A divergence within the input limits resets the node with a diagnostic.

    Explicit Euler with the coarsest accepted step at full rpm and helm blows up (an exponential
    instability, not a marginal one): reset with the reason, never NaN.
    """
    lim = input_limits(kvlcc2)
    rpm_max, rudder_max = lim.channels['rpm'].limit, lim.channels['rudder'].limit
    sim = ShipSimulator(kvlcc2, dt=lim.dt_max_s, x0=[0, 0, 0, 1.0, 0, 0], rpm=700.0,
                        rudder_rad=0.0, integrator='euler')
    assert sim.set_rpm(rpm_max) == '' and sim.set_rudder(rudder_max) == ''
    ok = [sim.step(10) for _ in range(200)]
    assert not all(ok)
    f = sim.failure
    assert f.reason.startswith(('implausible state', 'diverged', 'surge'))
    assert f.rpm == rpm_max and f.time_s > 0
    assert all(math.isfinite(v) for v in f.last_state)
    assert np.all(np.isfinite(sim.s))


@pytest.mark.parametrize('kw, words', [
    ({'dt': math.nan}, 'dt'), ({'dt': math.inf}, 'dt'), ({'dt': 0.0}, 'dt'),
    ({'dt': -1.0}, 'dt'), ({'dt': 1e-7}, 'dt'), ({'dt': 100.0}, 'dt'),
    ({'integrator': 'rk9'}, 'integrator'), ({'substeps': 0}, 'substeps'),
    ({'substeps': 2.5}, 'substeps'),
    ({'x0': [0, 0, 0, math.nan, 0, 0]}, 'not finite'),
    ({'x0': [math.inf, 0, 0, 3.0, 0, 0]}, 'not finite'),
    ({'x0': [1e300, 0, 0, 3.0, 0, 0]}, 'position'),
    ({'x0': [0, 0, 0, 0.0, 0, 0]}, 'surge'), ({'x0': [0, 0, 0, 1e3, 0, 0]}, 'surge'),
    ({'x0': [0, 0, 0, 3.0]}, 'shape'),
    ({'rpm': -50.0}, 'rpm'), ({'rpm': 0.0}, 'rpm'), ({'rpm': 1e308}, 'rpm'),
    ({'rpm': math.nan}, 'rpm'), ({'rudder_rad': 1000.0}, 'rudder'),
    ({'rudder_rad': math.nan}, 'rudder'),
])
def test_bad_settings_are_refused(suzaku, kw, words):
    args = {'dt': 0.1, 'x0': [0, 0, 0, 3.0, 0, 0], 'rpm': 106.0}
    args.update(kw)
    with pytest.raises(SimulationError, match=words):
        ShipSimulator(suzaku, **args)


floats = st.one_of(st.sampled_from(NASTY), st.floats(allow_nan=True, allow_infinity=True),
                   st.floats(-2000.0, 2000.0))


@settings(max_examples=150, deadline=None,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture])
@given(cmds=st.lists(st.tuples(floats, floats), min_size=1, max_size=6))
def test_any_command_sequence_keeps_the_state_finite_and_plausible(sim, cmds):
    sim.reset()
    lim = sim.limits
    rpm_max, rudder_max = lim.channels['rpm'].limit, lim.channels['rudder'].limit
    for rpm, rudder in cmds:
        p_rpm = sim.set_rpm(rpm)
        p_rud = sim.set_rudder(rudder)
        assert 0 < sim.rpm <= rpm_max and abs(sim.rudder) <= rudder_max
        if not (math.isfinite(rpm) and 0 < rpm <= rpm_max):
            assert p_rpm  # refused with a reason, never silently
        if not (math.isfinite(rudder) and abs(rudder) <= rudder_max):
            assert p_rud
        ok = sim.step(20)
        assert ok or sim.failure is not None
        assert plausible(sim)


@settings(max_examples=60, deadline=None)
@given(dt=floats, rpm=floats, rudder=floats, speed=floats)
def test_any_settings_are_either_refused_or_simulate_plausibly(suzaku, dt, rpm, rudder, speed):
    try:
        sim = ShipSimulator(suzaku, dt=dt, x0=[0, 0, 0, speed, 0, 0], rpm=rpm, rudder_rad=rudder)
    except SimulationError:
        return
    sim.step(max(1, min(200, int(20.0 / sim.dt))))
    assert plausible(sim)


# ---- astern and thrusters follow the ship's model family (issue 12) ------------------------
@pytest.fixture(scope='module')
def esso():
    from mmg_tuner.core.ship import load_ship
    return load_ship('esso_osaka_3m')


def test_astern_rpm_is_accepted_only_where_the_family_covers_it(suzaku, esso):
    rpm = input_limits(esso).channels['rpm']
    assert not rpm.forward_only and input_limits(suzaku).channels['rpm'].forward_only
    assert rpm.problem(-rpm.limit) == '' and rpm.problem(0.0) == ''
    assert 'beyond the plausible' in rpm.problem(-2 * rpm.limit)
    assert 'not finite' in rpm.problem(-math.inf)
    # the lowspeed ship backs down from rest with its propeller astern
    sim = ShipSimulator(esso, dt=0.1, x0=[0, 0, 0, 0.0, 0, 0], rpm=0.0)
    assert sim.set_rpm(-600.0) == '' and sim.rpm == -600.0
    assert sim.step(300)
    # measured u -0.081 m/s, x -1.25 m after 30 s: moving astern
    assert sim.s[3] < -0.04 and sim.s[0] < -0.6
    # SUZAKU (container family) still refuses it with the clear message, and holds its rpm
    z = ShipSimulator(suzaku, dt=0.1, x0=[0, 0, 0, 3.0, 0, 0], rpm=106.0)
    assert '<= 0 is outside the model' in z.set_rpm(-50.0) and z.rpm == 106.0
    with pytest.raises(SimulationError, match='surge'):
        ShipSimulator(suzaku, dt=0.1, x0=[0, 0, 0, 0.0, 0, 0], rpm=106.0)


def test_thrusters_turn_the_lowspeed_ship_and_are_validated(esso):
    def yaw_after(bow, stern, seconds=30.0):
        sim = ShipSimulator(esso, dt=0.1, x0=[0, 0, 0, 0.0, 0, 0], rpm=0.0)
        assert sim.set_thruster('bow', bow) == '' and sim.set_thruster('stern', stern) == ''
        assert sim.step(int(seconds / 0.1))
        return sim.s[2]

    still = yaw_after(0.0, 0.0)
    bow = yaw_after(15.0, 0.0)
    stern = yaw_after(0.0, 15.0)
    # + pushes to starboard: at the bow the ship turns to starboard, at the stern to port
    assert abs(still) < 0.01 and bow > 0.3 and stern < -0.3
    sim = ShipSimulator(esso, dt=0.1, x0=[0, 0, 0, 0.0, 0, 0], rpm=0.0)
    lim = sim.limits
    thr_max = lim.channels['bow_thruster'].limit
    assert thr_max == 30.0  # steering.max_thruster_rps of the YAML
    assert sim.set_thruster('bow', 10.0) == ''
    for bad in (math.nan, math.inf, -math.inf, 1e308, 2.5 * thr_max):
        assert 'ignored' in sim.set_thruster('bow', bad) and sim.bow == 10.0, bad
    assert 'clamped' in sim.set_thruster('stern', -45.0) and sim.stern == -30.0
    sim.reset()
    assert sim.bow == 0.0 and sim.stern == 0.0


def test_thrusters_are_refused_for_a_family_without_them(suzaku):
    ref = ShipSimulator(suzaku, dt=0.1, x0=[0, 0, 0, 3.0, 0, 0], rpm=106.0)
    sim = ShipSimulator(suzaku, dt=0.1, x0=[0, 0, 0, 3.0, 0, 0], rpm=106.0)
    for which in ('bow', 'stern'):
        problem = sim.set_thruster(which, 5.0)
        assert 'has no thrusters' in problem and 'container' in problem
    assert sim.bow == 0.0 and sim.stern == 0.0
    ref.set_rudder(0.2)
    sim.set_rudder(0.2)
    assert ref.step(200) and sim.step(200)
    np.testing.assert_array_equal(sim.s, ref.s)


@settings(max_examples=60, deadline=None,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture])
@given(cmds=st.lists(st.tuples(floats, floats, floats, floats), min_size=1, max_size=4))
def test_any_lowspeed_command_sequence_keeps_the_state_finite(esso, cmds):
    sim = ShipSimulator(esso, dt=0.1, x0=[0, 0, 0, 0.3, 0, 0], rpm=300.0)
    ch = sim.limits.channels
    rpm_max, rudder_max, thr_max = (ch[c].limit for c in ('rpm', 'rudder', 'bow_thruster'))
    for rpm, rudder, bow, stern in cmds:
        p = [sim.set_rpm(rpm), sim.set_rudder(rudder), sim.set_thruster('bow', bow),
             sim.set_thruster('stern', stern)]
        assert abs(sim.rpm) <= rpm_max and abs(sim.rudder) <= rudder_max
        assert max(abs(sim.bow), abs(sim.stern)) <= thr_max
        for value, problem in zip((bow, stern), p[2:]):
            if not (math.isfinite(value) and abs(value) <= thr_max):
                assert problem  # refused or clamped with a reason, never silently
        ok = sim.step(20)
        assert ok or sim.failure is not None
        assert plausible(sim)


def test_a_division_by_zero_in_the_model_is_a_failure_not_a_crash(esso):
    """
    Treat a division by zero in the model as a failure, not a crash.

    A rudder of 1e-300 rad made the lowspeed kernel raise ZeroDivisionError (compiled code raises
    it for x / 0.0), which would kill the node: it is a reset with a reason.
    """
    sim = ShipSimulator(esso, dt=0.1, x0=[0, 0, 0, 0.3, 0, 0], rpm=300.0)
    assert sim.set_rudder(1e-300) == ''
    if not sim.step(20):  # the model may since have been fixed: then it simply runs
        assert 'division by zero' in sim.failure.reason and sim.t == 0.0
    assert plausible(sim)


def test_lowspeed_cross_flow_integrals_survive_underflow():
    """The cause of the division above: b * b underflowed to 0 for b ~ 1e-300."""
    from mmg_tuner.core.models.lowspeed import cross_flow_integrals
    for a, b in ((1e-310, 1e-300), (0.0, 1e-300), (-1e-305, -1e-200)):
        iy, in_ = cross_flow_integrals(a, b)
        assert np.isfinite(iy) and np.isfinite(in_) and abs(iy) < 1e-300 and abs(in_) < 1e-300
    iy, in_ = cross_flow_integrals(0.1, 1.0)  # a sign change inside: the closed form still runs
    assert np.isfinite(iy) and iy != 0.0


@pytest.mark.parametrize('name', ['suzaku', 'kvlcc2', 'esso_osaka_3m', 'qiuxin_tug',
                                  'qiuxin_tug_simplified6', 'otter_usv'])
def test_every_input_channel_has_one_limit_the_simulator_and_readers_share(name):
    """One table: each input channel's clamp <= command cap <= recording cap, by name or unit."""
    from mmg_tuner.core.ship import load_ship

    ship = load_ship(name)
    lim = input_limits(ship)
    assert set(lim.channels) == set(ship.family.inputs)
    for ch, c in lim.channels.items():
        assert c.channel == ch and 0 <= c.limit <= c.plausible <= c.recorded, c
        value, problem = c.check(c.limit)
        assert value == c.limit and problem == ''
        if math.isfinite(c.plausible) and c.plausible > c.limit:   # clamped, said so
            value, problem = c.check(-(c.limit + c.plausible) / 2)
            assert value == -c.limit and 'clamped' in problem and c.basis in problem
        if math.isfinite(c.plausible):   # beyond the cap: refused, said so
            assert c.check(2 * c.plausible + 1)[0] is None
    assert lim.channel('bow_thruster').recorded == 200.0   # a topic the model may lack


def test_a_tug_without_a_shaft_limit_reads_data_but_is_not_commanded_and_limits_follow_the_yaml():
    """
    Refuse to command a tug without steering.max_thruster_rps, naming the key.

    Its limits still exist for the readers (no clamp to judge by); a changed limit in the
    YAML is a new table (the cache is keyed by the steering section).
    """
    from dataclasses import replace

    from mmg_tuner.core.ship import load_ship
    from mmg_tuner.errors import ConfigError
    tug = load_ship('qiuxin_tug')
    steering = dict(tug.extra['steering'])
    bare = replace(tug, extra={**tug.extra, 'steering': {k: v for k, v in steering.items()
                                                         if k != 'max_thruster_rps'}})
    lim = input_limits(bare)
    assert math.isinf(lim.channels['n_port'].limit) and lim.channels['n_port'].recorded == 200
    with pytest.raises(ConfigError, match='max_thruster_rps is needed to command n_port'):
        ShipSimulator(bare, dt=0.2, x0=[0, 0, 0, 0.5, 0, 0])
    slow = replace(tug, extra={**tug.extra, 'steering': {**steering, 'max_thruster_rps': 5.0,
                                                         'max_azimuth_deg': 10.0}})
    assert input_limits(slow).channels['n_port'].limit == 5.0
    assert input_limits(slow).channels['azimuth_port'].limit == pytest.approx(math.radians(10))
    assert input_limits(tug).channels['n_port'].limit == 12.0


def test_an_initial_command_beyond_the_limit_is_refused_and_said_so(suzaku):
    with pytest.raises(SimulationError, match=r'initial rudder command .* is outside the '
                                              r'\+-0\.785398 rad \(45\.0 deg\) limit'):
        ShipSimulator(suzaku, dt=0.1, x0=[0, 0, 0, 3.0, 0, 0], rpm=106.0, rudder_rad=1.0)
