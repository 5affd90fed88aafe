"""
The hybrid model's core (issue 14): the residual network's file, inference and training.

Inference (learn/residual.py) must equal the plain physics when the network is absent or
outputs zero, step by step in the node's stepper as in the offline simulation; the training's
differentiable simulation must equal the compiled one and its gradient the finite
differences; a small training must find an effect the physics lacks and nothing on clean data.
"""
from dataclasses import replace
import math
import re
import subprocess
import sys
import zipfile

import mmg_tuner as mt
from mmg_tuner.core.correction import FEATURES, PHYSICS_FEATURES
from mmg_tuner.core.dynamics import family_tag, N_ACT_STATES
from mmg_tuner.core.integrate import advance, physics_accelerations, start_state
from mmg_tuner.core.layout import INTEGRATORS, OK, PARAM_INDEX
from mmg_tuner.core.ship import load_ship
from mmg_tuner.core.stepper import apparent_wind_body
from mmg_tuner.data.generate import generate_trial, SensorNoise
from mmg_tuner.errors import ConfigError, MissingDependencyError, SimulationError
from mmg_tuner.learn.residual import (fitted_start, N_FEATURES, ResidualNet, ResidualStepper,
                                      simulate_hybrid, simulate_segments, zero_net)
import numpy as np
import pytest

SPECS = [('turning', 35), ('zigzag', 20), ('random', 30), ('zigzag', -15), ('turning', -25),
         ('random', 25)]
CI = {'window': 3, 'hidden': (16,), 'horizon_s': 20.0, 'epochs': 60, 'patience': 10,
      'integrator': 'rk4'}


def random_net(window=3, dt=1.0, hidden=(8,), scale=1e-3, seed=1, physics=True,
               physics_input=False):
    """
    Make a network with an output of about ``scale`` (small enough not to diverge).

    physics_input: it reads the physics' accelerations too (standardised by 1e-2: they
    matter to its output).
    """
    rng = np.random.default_rng(seed)
    nf = N_FEATURES + (3 if physics_input else 0)
    sizes = [window * nf, *hidden, 3]
    ws = tuple(rng.normal(0, 0.5, (o, i)) for i, o in zip(sizes[:-1], sizes[1:]))
    bs = tuple(rng.normal(0, 0.1, o) for o in sizes[1:])
    x_mean = rng.normal(0, 1, nf)   # (drawn in this order: the 9-feature nets of before)
    x_std = rng.uniform(0.5, 2, nf)
    x_mean[N_FEATURES:], x_std[N_FEATURES:] = 0.0, 1e-2
    return ResidualNet(window, dt, ws, bs, x_mean, x_std,
                       np.full(3, scale), physics, seed, {'note': 'test', 'values': [1, 2.5]},
                       FEATURES + (PHYSICS_FEATURES if physics_input else ()))


def make_trials(ship, effect: dict, duration=200.0):
    truth = ship.with_params(effect)
    return [generate_trial(truth, m, a, None, 106.0, 3.086, duration, 1.0, SensorNoise(), 10 + i,
                           f'{m}{a:+d}')[1] for i, (m, a) in enumerate(SPECS)]


@pytest.fixture(scope='module')
def trial(suzaku):
    return make_trials(suzaku, {}, 120.0)[2]


# ------------------------------------------------------------------------------- the file
def test_save_load_round_trip_is_exact(tmp_path):
    net = random_net()
    path = tmp_path / 'residual.npz'
    net.save(path)
    back = ResidualNet.load(path)
    assert (back.window, back.dt_s, back.physics, back.seed) == (3, 1.0, True, 1)
    assert back.meta == net.meta
    for a, b in zip(net.weights + net.biases + (net.x_mean, net.x_std, net.y_scale),
                    back.weights + back.biases + (back.x_mean, back.x_std, back.y_scale)):
        assert np.array_equal(a, b)
    with zipfile.ZipFile(path) as z:   # portable: plain .npy arrays, nothing pickled
        assert all(n.endswith('.npy') for n in z.namelist())
    np.load(path, allow_pickle=False)['meta']


def _rewrite(src, dst, drop=(), change=None):
    with np.load(src, allow_pickle=False) as z:
        d = {k: z[k] for k in z.files if k not in drop}
    d.update(change or {})
    with open(dst, 'wb') as f:
        np.savez(f, **d)


def test_load_names_the_file_and_the_bad_key(tmp_path):
    good = tmp_path / 'good.npz'
    random_net().save(good)
    with pytest.raises(ConfigError, match='missing.npz.*does not exist'):
        ResidualNet.load(tmp_path / 'missing.npz')
    junk = tmp_path / 'junk.npz'
    junk.write_bytes(b'not a zip file at all')
    with pytest.raises(ConfigError, match='junk.npz'):
        ResidualNet.load(junk)
    cut = tmp_path / 'cut.npz'
    cut.write_bytes(good.read_bytes()[:200])
    with pytest.raises(ConfigError, match='cut.npz'):
        ResidualNet.load(cut)
    for key in ('y_scale', 'W1', 'window', 'meta'):
        bad = tmp_path / f'no_{key}.npz'
        _rewrite(good, bad, drop=(key,))
        with pytest.raises(ConfigError, match=f"no_{key}.npz.*'{key}'"):
            ResidualNet.load(bad)
    bad = tmp_path / 'shape.npz'
    _rewrite(good, bad, change={'W0': np.zeros((8, 5))})
    with pytest.raises(ConfigError, match="shape.npz.*'W0'"):
        ResidualNet.load(bad)
    bad = tmp_path / 'nan.npz'
    _rewrite(good, bad, change={'x_std': np.full(N_FEATURES, np.nan)})
    with pytest.raises(ConfigError, match="nan.npz.*'x_std'"):
        ResidualNet.load(bad)


def test_a_network_reading_the_physics_round_trips_and_a_wrong_name_is_refused(tmp_path):
    net = random_net(physics_input=True)
    path = tmp_path / 'residual.npz'
    net.save(path)
    back = ResidualNet.load(path)
    assert back.physics_input and back.features == net.features and back.n_features == 12
    assert np.array_equal(back.weights[0], net.weights[0])
    bad = tmp_path / 'bad.npz'
    _rewrite(path, bad, change={'features': np.array(FEATURES + ('du', 'dv', 'dr'))})
    with pytest.raises(ConfigError, match="bad.npz.*'features'.*phys_du"):
        ResidualNet.load(bad)
    with pytest.raises(ValueError, match='physics=.du, dv, dr'):   # the caller must give them
        ResidualStepper(net).accelerations(np.zeros(6), (60.0, 0.0), (0.0, 0.0))


# -------------------------------------------------------------------------------- inference
def _pass_through(dt, eps=1e-4, window=2):
    """Return a pure network whose output is the physics' input of its last row (to eps^2)."""
    nf = N_FEATURES + 3
    w0 = np.zeros((3, window * nf))
    w0[:, (window - 1) * nf + N_FEATURES:] = eps * np.eye(3)
    return ResidualNet(window, dt, (w0, np.eye(3) / eps), (np.zeros(3), np.zeros(3)),
                       np.zeros(nf), np.ones(nf), np.ones(3), False,
                       features=FEATURES + PHYSICS_FEATURES)


def test_the_physics_input_steps_the_gear_over_a_sample_whatever_the_substeps(suzaku):
    """
    In the sample loop the physics' input advances the gear over the sample, not a substep.

    As the training's rows do (one actuator step per sample): a pass-through network's
    output at each sample equals ``physics_accelerations`` over the 0.5 s sample at the
    simulated state, with the lagging gear where its exact response puts it, though the run
    integrates two 0.25 s substeps (over a substep the gear would be 3-4 degrees short).
    """
    from mmg_tuner.core.trial import Trial
    ship = suzaku.with_params({'rudder_lag_tau': 2.0})
    p, tag, T, dt, tau = ship.params, family_tag(ship.kind), 30, 0.5, 2.0
    x0 = [0.0, 0.0, 0.0, 3.0, 0.0, 0.0]
    rudder = np.where(np.arange(T) < 10, 0.0, 0.6)
    tr = Trial(np.arange(T) * dt, np.tile(x0, (T, 1)),
               np.column_stack([np.full(T, 100.0), rudder]))
    states, res, _, _ = simulate_segments(ship, _pass_through(dt), tr, 'euler', 0.0, 2)
    inputs = np.ascontiguousarray(tr.input_array(ship.family.channels))
    for k in (10, 11, 12, 20):
        gear = np.zeros(N_ACT_STATES)   # the exact first-order gear at the sample's start
        gear[0] = ship['rudder_offset'] + 0.6 * (1.0 - math.exp(-(k - 10) * dt / tau))
        want = physics_accelerations(tag, p, states[k], gear, inputs, k, 0.0, T, dt)
        np.testing.assert_allclose(res[k], want, rtol=1e-6, atol=1e-10)


def test_a_pure_network_passing_the_physics_through_is_the_physics(suzaku, trial):
    """
    A pure network whose output is its physics input is the physics (Euler, restarts too).

    Its hidden layer reads the last row's physics columns scaled by eps (tanh(eps a) / eps
    = a to eps^2): Euler's step uses the accelerations at the sample's start, exactly what
    the features hold, so the runs agree; a feature taken at another state, or from other
    inputs or actuators, would not.
    """
    net = _pass_through(trial.dt)
    for restart in (None, 30.0):
        ref = simulate_segments(suzaku, None, trial, 'euler', restart)[0]
        got = simulate_segments(suzaku, net, trial, 'euler', restart)[0]
        np.testing.assert_allclose(got, ref, rtol=1e-8, atol=1e-8)
    rk4 = simulate_segments(suzaku, net, trial, 'rk4', None)[0]   # held, not re-evaluated
    assert np.max(np.abs(rk4 - simulate_segments(suzaku, None, trial, 'rk4')[0])) > 1e-4


def test_fitted_start_is_the_tuning_objectives_rule(trial):
    from mmg_tuner.tuning.report import start_state as tuning_start
    assert np.array_equal(fitted_start(trial), tuning_start(trial))


@pytest.mark.parametrize('integrator', ['rk4', 'euler'])
def test_no_net_and_a_zero_net_are_the_physics(suzaku, trial, integrator):
    ref = mt.simulate(suzaku, trial, integrator=integrator)
    assert np.array_equal(simulate_hybrid(suzaku, None, trial, integrator=integrator).states,
                          ref.states)
    zero = simulate_hybrid(suzaku, zero_net(4, trial.dt), trial, integrator=integrator)
    np.testing.assert_allclose(zero.states, ref.states, rtol=1e-12, atol=1e-12)
    # a net that does something moves the trajectory (the comparison above is not vacuous)
    other = simulate_hybrid(suzaku, random_net(scale=1e-3), trial, integrator=integrator)
    assert np.max(np.abs(other.states[:, 1] - ref.states[:, 1])) > 0.1


def test_restarts_follow_evaluate(suzaku, trial):
    from mmg_tuner.tuning.evaluate import predict
    ref, _, _ = predict(suzaku, trial, 30.0, 'rk4')
    got, _, fail_t, _ = simulate_segments(suzaku, None, trial, 'rk4', 30.0)
    assert fail_t is None and np.array_equal(got, ref)
    got0, _, _, _ = simulate_segments(suzaku, zero_net(3, trial.dt), trial, 'rk4', 30.0)
    np.testing.assert_allclose(got0, ref, rtol=1e-12, atol=1e-12)


def test_pure_network_ignores_the_physics(suzaku, trial):
    """
    Check that a pure network ignores the family.

    physics=False: the accelerations are the network's alone, so the family's parameters
    do not matter (only the kinematics).
    """
    net = random_net(scale=1e-3, physics=False)
    a = simulate_hybrid(suzaku, net, trial).states
    b = simulate_hybrid(suzaku.with_params({'R_0': 0.05, 'Y_v': -1.0}), net, trial).states
    assert np.array_equal(a, b)


def test_wrong_sample_interval_is_refused(suzaku, trial):
    with pytest.raises(SimulationError, match='resample'):
        simulate_hybrid(suzaku, random_net(dt=0.5), trial)


@pytest.mark.parametrize('integrator,physics_input',
                         [pytest.param('euler', False, marks=pytest.mark.slow), ('rk4', False),
                          ('rk4', True)])
def test_stepper_reproduces_simulate_hybrid(suzaku, trial, integrator, physics_input):
    net = random_net(scale=1e-3, physics_input=physics_input)
    ref = simulate_hybrid(suzaku, net, trial, integrator=integrator)
    p = np.array(suzaku.params)
    s = np.empty(6)
    start_state(p, fitted_start(trial), s)
    stepper = ResidualStepper(net)
    stepper.reset(s)
    gear = np.zeros(N_ACT_STATES)   # the screw-and-rudder actuator's state: the actual angle
    gear[0] = trial.controls[0, 1] + suzaku['rudder_offset']
    tag = family_tag(suzaku.kind)
    got = [s.copy()]
    for k in range(len(trial) - 1):
        rpm, rudder = trial.controls[k]
        row = np.array([[rpm, rudder, np.nan, np.nan]])   # one sample: commands, no wind
        seen = (s, (rpm, rudder, 0.0, 0.0), apparent_wind_body(suzaku, s))
        if physics_input:
            seen += (physics_accelerations(tag, p, s, gear, row, 0, 0.0, 1, trial.dt),)
        a = stepper.accelerations(*seen)
        st = advance(tag, p, s, gear, row, 0, 0.0, 1, trial.dt, 1, INTEGRATORS[integrator], *a,
                     True)
        assert st == OK
        got.append(s.copy())
    np.testing.assert_allclose(np.array(got), ref.states, rtol=1e-12, atol=1e-12)


def test_the_node_stepper_feeds_a_network_the_physics_as_offline(suzaku):
    """
    The node's ShipSimulator with a network reading the physics equals the offline run.

    A lagging steering gear, a rudder step mid-run, the node's 0.25 s steps against 0.5 s
    samples integrated in two substeps: the physics' input is taken over the sample interval
    both ways (its actuators' step must not depend on the simulator's step).
    """
    from mmg_tuner.core.stepper import ShipSimulator
    from mmg_tuner.core.trial import Trial
    ship = suzaku.with_params({'rudder_lag_tau': 2.0})
    net = random_net(window=3, dt=0.5, scale=1e-3, physics_input=True)
    x0 = [0.0, 0.0, 0.0, 3.0, 0.0, 0.0]
    sim = ShipSimulator(ship, dt=0.25, x0=x0, rpm=100.0, rudder_rad=0.0, residual=net)
    assert sim.step(20)   # 10 samples straight, then 35 deg
    sim.set_rudder(0.6)
    assert sim.step(180)
    T = 101
    rudder = np.where(np.arange(T) < 10, 0.0, 0.6)
    tr = Trial(np.arange(T) * 0.5, np.tile(x0, (T, 1)),
               np.column_stack([np.full(T, 100.0), rudder]))
    off = simulate_hybrid(ship, net, tr, restart_every_s=0.0, substeps=2)
    np.testing.assert_allclose(sim.observed(), off.states[-1], rtol=1e-9, atol=1e-9)
    blind = replace(net, x_std=np.concatenate([net.x_std[:N_FEATURES], np.full(3, 1e9)]))
    plain = simulate_hybrid(ship, blind, tr, restart_every_s=0.0, substeps=2)
    assert not np.allclose(plain.states[-1], off.states[-1], atol=1e-3)   # the input matters


def test_the_history_rows_hold_the_physics_of_each_measured_sample(suzaku):
    """
    trial_rows' physics columns: the loop's own physics at each measured model state.

    With a current, an antenna offset, measured wind that changes and the parameters given
    (not the ship's): each row equals ``physics_accelerations`` at the model state of that
    sample (antenna to midship, through the water) with that sample's wind and inputs (the
    gear without lag: its state is the recorded angle; the lag is the node test's).
    """
    from mmg_tuner.core.trial import Trial
    from mmg_tuner.learn.residual import trial_rows
    ship = suzaku.with_params({'current_speed': 0.2, 'current_dir': 1.0, 'antenna_x': 2.0})
    p = ship.with_params({'N_r': 1.2 * ship['N_r']}).params
    T = 60
    rng = np.random.default_rng(3)
    states = np.column_stack([np.cumsum(rng.normal(0, 1, T)), rng.normal(0, 1, T),
                              rng.normal(0, 0.1, T), 3 + rng.normal(0, 0.1, T),
                              rng.normal(0, 0.1, T), rng.normal(0, 0.01, T)])
    ctrl = np.column_stack([np.full(T, 100.0), np.where(np.arange(T) < 20, 0.0, 0.5)])
    wind = np.column_stack([np.linspace(-3, 5, T), np.full(T, 2.0)])
    tr = Trial(np.arange(T) * 0.5, states, ctrl, wind=wind)
    rows, ms = trial_rows(ship, tr, True, p)
    assert rows.shape == (T, N_FEATURES + 3)
    inputs = np.ascontiguousarray(tr.input_array(ship.family.channels))
    tag = family_tag(ship.kind)
    for k in (0, 19, 20, 21, 59):
        gear = np.zeros(N_ACT_STATES)
        gear[0] = ctrl[k, 1] + ship['rudder_offset']
        q = p.copy()
        q[PARAM_INDEX['wind_speed']] = math.hypot(*wind[k])
        q[PARAM_INDEX['wind_dir']] = math.atan2(-wind[k, 1], -wind[k, 0])
        want = physics_accelerations(tag, q, ms[k], gear, inputs, k, 0.0, T, 0.5)
        np.testing.assert_allclose(rows[k, N_FEATURES:], want, rtol=1e-9,
                                   atol=1e-9 * np.max(np.abs(want)))
    assert not np.allclose(rows[:, N_FEATURES:], trial_rows(ship, tr, True)[0][:, N_FEATURES:])


def test_core_residual_runs_without_jax():
    code = ('import sys; import mmg_tuner.learn.residual; import mmg_tuner.learn; '
            'assert not any(m.split(".")[0] in ("jax", "equinox", "optax") for m in sys.modules)')
    subprocess.run([sys.executable, '-c', code], check=True)


def test_missing_jax_says_how_to_install(monkeypatch, suzaku, trial):
    from mmg_tuner.learn import train_residual
    monkeypatch.setitem(sys.modules, 'jax', None)   # import jax -> ImportError
    with pytest.raises(MissingDependencyError, match='pip install jax equinox optax'):
        train_residual(suzaku, [trial])


def test_config_names_the_bad_option():
    from mmg_tuner.learn import ResidualConfig
    for kw, name in (({'window': 0}, 'window'), ({'hidden': ()}, 'hidden'),
                     ({'integrator': 'rk45'}, 'integrator'), ({'l2': -1.0}, 'l2'),
                     ({'horizon_s': math.nan}, 'horizon_s'), ({'balance': 'kind'}, 'balance'),
                     ({'select': 'worst'}, 'select')):
        with pytest.raises(ConfigError, match=name):
            ResidualConfig(**kw)


# ------------------------------------------------------------------------ the physics bridge
def _states_inputs(ship, rng, n):
    """Random states, actuator tuples (``Family.outputs``) and winds in the family's range."""
    if ship.model == 'lowspeed':
        uvr = rng.uniform([-0.3, -0.2, -0.1], [0.8, 0.2, 0.1], (n, 3))
        act = np.column_stack([rng.uniform(-20, 20, n), rng.uniform(-0.7, 0.7, n),
                               rng.uniform(-25, 25, (n, 2))])
        wind = np.column_stack([rng.uniform(0, 5, n), rng.uniform(-4, 4, n)])
    else:
        U = 3.0 if ship.name.lower().startswith('suz') else 1.2
        uvr = rng.uniform([0.6 * U, -0.1 * U, -0.02], [1.1 * U, 0.1 * U, 0.02], (n, 3))
        act = np.column_stack([rng.uniform(5, 15, n), rng.uniform(-0.6, 0.6, n)])
        wind = np.column_stack([rng.uniform(0, 8, n), rng.uniform(-4, 4, n)])
    S = np.column_stack([rng.uniform(-50, 50, (n, 2)), rng.uniform(-4, 4, n), uvr])
    return S, act, wind


@pytest.fixture(scope='module', params=['suzaku', 'kvlcc2', 'esso_osaka_3m'])
def any_ship(request):
    ship = load_ship(request.param)
    if ship.model != 'lowspeed':  # wind loads need windage; give the others a current too
        ship = ship.with_params({'current_speed': 0.1, 'current_dir': 0.7})
    return ship


def test_bridge_forward_is_the_compiled_kernel(any_ship):
    pytest.importorskip('jax')
    import jax.numpy as jnp

    from mmg_tuner.core.dynamics import derivative
    from mmg_tuner.learn._engine import physics_fn
    ship = any_ship
    S, A, Wd = _states_inputs(ship, np.random.default_rng(4), 64)
    args = (jnp.asarray(S), jnp.asarray(A), jnp.asarray(Wd))
    # the callback calls the compiled kernel itself: to the bit; the FFI handler is compiled
    # apart (fast-math may round an operation differently): to 1e-12
    F_cb = np.asarray(physics_fn(ship.kind, ship.params, ffi=False)(*args))
    F = np.asarray(physics_fn(ship.kind, ship.params)(*args))
    p = np.array(ship.params)
    out = np.empty(6)
    for b in range(S.shape[0]):
        p[PARAM_INDEX['wind_speed']], p[PARAM_INDEX['wind_dir']] = Wd[b]
        derivative(family_tag(ship.kind), p, S[b].copy(), tuple(A[b]), out)
        assert np.array_equal(F_cb[b], out)
        np.testing.assert_allclose(F[b], out, rtol=1e-12, atol=1e-12 * np.abs(out).max())


def test_bridge_ffi_handler_is_taken_and_equals_the_callback(any_ship):
    """
    The physics runs as an XLA FFI handler, equal to the pure_callback reference.

    Values and vector-Jacobian products, on a batch and under jax.vmap (leading axes): a
    handler that read a wrong offset, row count or argument, or silently fell back to the
    callback, fails. Values to 1e-12 (the handler's kernel is compiled apart, fast-math may
    round an operation differently), the Jacobian's products to 1e-6 (forward differences
    multiply such an ulp by 1 / 1.5e-8).
    """
    pytest.importorskip('jax')
    import jax
    import jax.numpy as jnp

    from mmg_tuner.learn import _engine
    ship = any_ship
    rng = np.random.default_rng(5)
    S, A, Wd = (jnp.asarray(x) for x in _states_inputs(ship, rng, 24))
    fast = _engine.physics_fn(ship.kind, ship.params)
    ref = _engine.physics_fn(ship.kind, ship.params, ffi=False)
    assert _engine._FFI_TARGETS[ship.kind] is True   # registered and self-tested
    G = jnp.asarray(rng.normal(size=S.shape))
    Fa, vjp_a = jax.vjp(lambda s: fast(s, A, Wd), S)
    Fb, vjp_b = jax.vjp(lambda s: ref(s, A, Wd), S)

    def close(a, b, rtol):
        a, b = np.asarray(a), np.asarray(b)
        np.testing.assert_allclose(a, b, rtol=rtol, atol=rtol * np.abs(b).max())

    close(Fa, Fb, 1e-12)
    close(vjp_a(G)[0], vjp_b(G)[0], 1e-6)
    # the parameters are read at every call, not kept from the first registration
    p2 = np.array(ship.params)
    p2[PARAM_INDEX['current_speed']] += 0.3   # the current enters every family's dx, dy
    other = _engine.physics_fn(ship.kind, p2)(S, A, Wd)
    assert not np.allclose(np.asarray(other), np.asarray(Fa), rtol=1e-6)
    close(other, _engine.physics_fn(ship.kind, p2, ffi=False)(S, A, Wd), 1e-12)
    # three batches of eight under vmap: the handler sees (3, 8, 6) and must treat it as 24 rows
    batched = jax.vmap(lambda s, a, w: fast(s, a, w))(S.reshape(3, 8, 6),
                                                      A.reshape(3, 8, -1), Wd.reshape(3, 8, 2))
    close(np.asarray(batched).reshape(24, 6), ref(S, A, Wd), 1e-12)


def test_bridge_falls_back_to_the_callback_when_xla_refuses_the_handler(monkeypatch, caplog):
    """A handler XLA refuses (e.g. a C API it does not speak) leaves the callback, and says so."""
    pytest.importorskip('jax')
    import jax.numpy as jnp

    from mmg_tuner.learn import _engine
    ship = mt.load_ship('kvlcc2')

    def refused(kind):
        raise RuntimeError('XLA FFI handler API version 9.0 is not supported')

    monkeypatch.setattr(_engine, 'ffi_handler', refused)
    monkeypatch.setattr(_engine, '_FFI_TARGETS', {})
    S, A, Wd = (jnp.asarray(x) for x in _states_inputs(ship, np.random.default_rng(6), 8))
    with caplog.at_level('WARNING', logger='mmg_tuner.learn._engine'):
        F = _engine.physics_fn(ship.kind, ship.params)(S, A, Wd)
    assert 'pure_callback' in caplog.text and 'API version 9.0' in caplog.text
    assert _engine._FFI_TARGETS == {ship.kind: False}
    ref = _engine.physics_fn(ship.kind, ship.params, ffi=False)(S, A, Wd)
    assert np.array_equal(np.asarray(F), np.asarray(ref))   # the callback, both times


def test_bridge_gradient_matches_finite_differences(any_ship):
    """
    Check the VJP (compiled Jacobian) against central differences of the whole kernel.

    On a scalar that mixes every output: a transposed or mis-indexed Jacobian fails.
    """
    pytest.importorskip('jax')
    import jax
    import jax.numpy as jnp

    from mmg_tuner.learn._engine import physics_fn
    ship = any_ship
    rng = np.random.default_rng(9)
    S, A, Wd = _states_inputs(ship, rng, 16)
    f = physics_fn(ship.kind, ship.params)
    G = rng.normal(size=S.shape)
    _, vjp = jax.vjp(lambda s: f(s, jnp.asarray(A), jnp.asarray(Wd)), jnp.asarray(S))
    grad = np.asarray(vjp(jnp.asarray(G))[0])

    def scalar(s):
        return np.sum(G * np.asarray(f(jnp.asarray(s), jnp.asarray(A), jnp.asarray(Wd))), axis=1)

    fd = np.zeros_like(S)
    for j in range(6):
        h = 1e-5 * np.maximum(1.0, np.abs(S[:, j]))
        up, dn = S.copy(), S.copy()
        up[:, j] += h
        dn[:, j] -= h
        fd[:, j] = (scalar(up) - scalar(dn)) / (2 * h)
    scale = np.max(np.abs(fd), axis=1, keepdims=True)
    assert np.all(np.abs(grad - fd) <= 1e-5 * scale + 1e-12)
    assert np.all(grad[:, :2] == 0.0)  # positions do not enter the dynamics


def test_bridge_parameter_gradient_matches_finite_differences(any_ship):
    """
    The free coefficients' VJP against central differences of the whole kernel.

    The handler's parameter Jacobian (its third result) and the callback's agree, and both
    match differences of the kernel in each coefficient: a mis-indexed slot, a step left in
    the parameters or a transposed product fails.
    """
    pytest.importorskip('jax')
    import jax
    import jax.numpy as jnp

    from mmg_tuner.learn._engine import physics_fn
    ship = any_ship
    names = ship.tuning_targets[:4]
    slots = np.array([PARAM_INDEX[n] for n in names])
    theta0 = np.array([ship[n] for n in names])
    steps = 1.5e-8 * np.maximum(np.abs(theta0), 1e-3)
    rng = np.random.default_rng(10)
    S, A, Wd = (jnp.asarray(x) for x in _states_inputs(ship, rng, 16))
    G = rng.normal(size=S.shape)
    ref = physics_fn(ship.kind, ship.params, ffi=False)
    grads = []
    for ffi in (True, False):
        f = physics_fn(ship.kind, ship.params, ffi, slots, steps)
        F, vjp = jax.vjp(lambda t: f(S, A, Wd, t), jnp.asarray(theta0))
        grads.append(np.asarray(vjp(jnp.asarray(G))[0]))
        # the values are the kernel's with the coefficients in place
        np.testing.assert_allclose(np.asarray(F), np.asarray(ref(S, A, Wd)), rtol=1e-12,
                                   atol=1e-12)
    np.testing.assert_allclose(grads[0], grads[1], rtol=1e-6, atol=1e-6 * np.abs(grads[1]).max())
    fd = np.zeros(len(names))
    for k in range(len(names)):
        h = 1e-5 * max(abs(theta0[k]), 1e-3)
        up = ship.params.copy()
        dn = ship.params.copy()
        up[slots[k]] += h
        dn[slots[k]] -= h
        F_up = np.asarray(physics_fn(ship.kind, up, ffi=False)(S, A, Wd))
        F_dn = np.asarray(physics_fn(ship.kind, dn, ffi=False)(S, A, Wd))
        fd[k] = np.sum(G * (F_up - F_dn)) / (2 * h)
    assert np.any(np.abs(fd) > 0)
    assert np.all(np.abs(grads[0] - fd) <= 1e-4 * np.abs(fd).max() + 1e-12), (grads[0], fd)


def _window_batch(ship, trial, net, k0, H):
    from mmg_tuner.learn._windows import cut, prepare
    w = cut([prepare(ship, trial, net.physics_input)], net.window, H, 1).take(
        [k0 - net.window + 1])
    return {'x0': w.x0, 'hist': w.hist, 'inp': w.inp, 'act': w.act, 'wind': w.wind,
            'target': w.target}


@pytest.mark.parametrize('integrator', ['euler', 'rk4'])
def test_training_simulation_equals_inference(suzaku, trial, integrator):
    """
    Check that the JAX window simulation equals the compiled one.

    The window the loss differentiates is simulate_hybrid's run restarted at the same sample
    (same features, window, residual hold, integrator).
    """
    pytest.importorskip('jax')
    import equinox as eqx
    import jax
    import jax.numpy as jnp

    from mmg_tuner.learn._engine import make_simulator, MLP
    ship = suzaku.with_params({'antenna_x': 1.0, 'current_speed': 0.2, 'current_dir': 1.0})
    net = random_net(scale=2e-3)
    k0, H = 40, 20
    model = MLP([net.n_inputs, 8, 3], jax.random.PRNGKey(0))
    model = eqx.tree_at(lambda m: [la.weight for la in m.layers] + [la.bias for la in m.layers],
                        model, [jnp.asarray(x) for x in net.weights + net.biases])
    sim = make_simulator(ship.kind, ship.params, True, integrator == 'rk4', trial.dt,
                         net.x_mean, net.x_std, net.y_scale)
    b = _window_batch(ship, trial, net, k0, H)
    obs, _ = sim(model, b['x0'], b['hist'], b['inp'], b['act'], b['wind'])
    ref, _, _, _ = simulate_segments(ship, net, trial.slice(0.0, None), integrator, float(k0))
    np.testing.assert_allclose(np.asarray(obs)[0], ref[k0 + 1:k0 + H + 1], rtol=1e-9,
                               atol=1e-9)


def test_loss_gradient_through_the_simulation(suzaku, trial):
    """
    Check d loss / d weights through 15 simulated steps and the compiled physics.

    JAX's gradient against a central difference along a random direction in weight space.
    """
    pytest.importorskip('jax')
    import equinox as eqx
    import jax
    import jax.numpy as jnp

    from mmg_tuner.learn._engine import MLP, make_loss, make_simulator
    net = random_net(scale=2e-3)
    sim = make_simulator(suzaku.kind, suzaku.params, True, True, trial.dt, net.x_mean,
                         net.x_std, net.y_scale)
    _, total = make_loss(sim, np.std(trial.states, axis=0), net.y_scale, 0.1, True)
    b = _window_batch(suzaku, trial, net, 30, 15)
    w = jnp.ones(1)
    model = MLP([net.n_inputs, 6, 3], jax.random.PRNGKey(3))
    model = eqx.tree_at(lambda m: m.layers[-1].weight, model,
                        jnp.asarray(np.random.default_rng(2).normal(0, 0.3, (3, 6))))
    params, static = eqx.partition(model, eqx.is_array)
    grads = jax.grad(lambda pr: total(eqx.combine(pr, static), b, w)[0])(params)
    rng = np.random.default_rng(5)
    direction = jax.tree_util.tree_map(lambda x: jnp.asarray(rng.normal(size=x.shape)), params)
    pairs = zip(jax.tree_util.tree_leaves(grads), jax.tree_util.tree_leaves(direction))
    analytic = sum(float(jnp.sum(g * d)) for g, d in pairs)

    def at(eps):
        pr = jax.tree_util.tree_map(lambda x, d: x + eps * d, params, direction)
        return float(total(eqx.combine(pr, static), b, w)[0])

    h = 1e-5
    fd = (at(h) - at(-h)) / (2 * h)
    assert abs(analytic) > 1e-8
    assert analytic == pytest.approx(fd, rel=1e-5)


# ------------------------------------------------------------------------------ training
def _heldout_index(ship, net, trials):
    """Return the paper's index (100 s restarts, sigma pooled over the held-out trials)."""
    sig = np.std(np.concatenate([t.states for t in trials]), axis=0)
    e = [simulate_hybrid(ship, net, t, restart_every_s=100.0).states - t.states for t in trials]
    e = np.concatenate(e)
    e[:, 2] = (e[:, 2] + math.pi) % (2 * math.pi) - math.pi
    return float(np.mean(np.sum((e / sig) ** 2, axis=1)))


@pytest.fixture(scope='module')
def hidden_fit(suzaku):
    pytest.importorskip('jax')
    from mmg_tuner.learn import ResidualConfig, train_residual
    trials = make_trials(suzaku, {'yaw_moment_bias': 0.002})
    fit = train_residual(suzaku, trials[:4], config=ResidualConfig(**CI, seed=0))
    return fit, trials


def test_residual_learns_an_effect_the_physics_lacks(suzaku, hidden_fit):
    fit, trials = hidden_fit
    test = trials[4:]
    physics, hybrid = _heldout_index(suzaku, None, test), _heldout_index(suzaku, fit.net, test)
    assert hybrid <= 0.7 * physics, (physics, hybrid)
    assert fit.val_gain > 0.05 and 0.0 < fit.share < 1.0
    assert fit.net.meta['seed'] == 0 and fit.net.meta['trials'] == [t.name for t in trials[:4]]
    assert fit.history[0]['val'] == fit.physics_val_loss


def test_training_is_reproducible_with_a_seed(suzaku, hidden_fit):
    from mmg_tuner.learn import ResidualConfig, train_residual
    fit, trials = hidden_fit
    cfg = ResidualConfig(**{**CI, 'epochs': 3}, seed=0)
    a = train_residual(suzaku, trials[:4], config=cfg)
    b = train_residual(suzaku, trials[:4], config=cfg)
    c = train_residual(suzaku, trials[:4], config=replace(cfg, seed=1))
    assert all(np.array_equal(x, y) for x, y in zip(a.net.weights, b.net.weights))
    assert not np.array_equal(a.net.weights[0], c.net.weights[0])


def test_residual_finds_nothing_on_clean_data(suzaku):
    pytest.importorskip('jax')
    from mmg_tuner.learn import ResidualConfig, train_residual
    trials = make_trials(suzaku, {})
    fit = train_residual(suzaku, trials[:4], config=ResidualConfig(**CI, seed=0))
    test = trials[4:]
    physics, hybrid = _heldout_index(suzaku, None, test), _heldout_index(suzaku, fit.net, test)
    assert fit.share < 0.1
    assert abs(hybrid / physics - 1.0) < 0.1, (physics, hybrid)


def test_joint_training_moves_the_coefficient_the_data_pull_on(suzaku):
    """
    Physics coefficients trained with the network move toward the truth's.

    The truth's yaw damping N_r is 30 % larger than the physics'; trained together, N_r
    (free in a box, no prior) moves at least a third of the way, and the fit records it (a
    joint training that never reached the coefficients, or moved them the wrong way, fails).
    """
    pytest.importorskip('jax')
    from mmg_tuner.learn import JointCoefficients, ResidualConfig, train_residual
    n_r = suzaku['N_r']
    truth = 1.3 * n_r
    trials = make_trials(suzaku, {'N_r': truth})
    lo, hi = sorted((0.5 * n_r, 1.5 * n_r))
    rpm = suzaku['rpm_scale']   # acts on the commands, before the kernel: not trained
    jc = JointCoefficients(('N_r', 'rpm_scale'), (n_r, rpm), (lo, 0.5 * rpm), (hi, 1.5 * rpm),
                           (n_r, rpm), 0.0)
    # Adam moves z by about the learning rate a step (box widths): 1e-2 reaches the truth's
    # N_r within the CI's few steps (3e-3, the default, gets a quarter of the way)
    fit = train_residual(suzaku, trials[:4], coefficients=jc,
                         config=ResidualConfig(**{**CI, 'learning_rate': 1e-2}, seed=0))
    moved = fit.coefficients['N_r']
    assert (moved - n_r) / (truth - n_r) > 1 / 3, (n_r, moved, truth)
    assert fit.net.meta['coefficients'] == fit.coefficients and set(fit.coefficients) == {'N_r'}
    assert any('N_r' in note for note in fit.notes)
    assert any(n.startswith('not trained with the network: rpm_scale') for n in fit.notes)
    with pytest.raises(mt.MmgTunerError, match='current'):   # the features read it
        train_residual(suzaku, trials[:4], config=ResidualConfig(**CI, seed=0),
                       coefficients=JointCoefficients(('current_speed',), (0.0,), (0.0,),
                                                      (0.5,), (0.0,)))
    with pytest.raises(ConfigError, match='hold its start'):   # a box without the start
        JointCoefficients(('N_r',), (n_r,), (2 * abs(n_r),), (3 * abs(n_r),), (n_r,))


def test_joint_training_goes_on_from_an_ensemble_keeping_its_members_apart(suzaku, hidden_fit):
    """
    Training on from a trained ensemble: it starts there, and stays an ensemble.

    Epoch 0 is the start's validation loss (not the physics alone's); the deeper layer keeps
    its block-diagonal zeros, so members() splits the result into networks whose mean is it;
    with a significance no epoch can meet, the start comes back unchanged (to rounding).
    """
    from mmg_tuner.errors import TuningError
    from mmg_tuner.learn import ensemble, JointCoefficients, ResidualConfig, train_residual
    from mmg_tuner.learn.train import members
    _, trials = hidden_fit
    cfg = ResidualConfig(**{**CI, 'hidden': (6, 5), 'epochs': 3}, seed=0)
    # members barely trained (one epoch, a small step) on other trials than the training's:
    # the start is rewritten in other scales and far from the best the training can reach
    fits = [train_residual(suzaku, ts, config=replace(cfg, seed=s, significance=0.0, epochs=1,
                                                      learning_rate=1e-3))
            for s, ts in ((0, trials[:3]), (1, trials[1:4]))]
    start = ensemble([f.net for f in fits])
    n_r = suzaku['N_r']
    lo, hi = sorted((0.5 * n_r, 1.5 * n_r))
    jc = JointCoefficients(('N_r',), (n_r,), (lo,), (hi,), (n_r,), 0.0)
    fit = train_residual(suzaku, trials[:4], coefficients=jc, start=start,
                         config=replace(cfg, significance=0.0, learning_rate=1e-2))
    assert fit.history[0]['val'] != fit.physics_val_loss
    assert fit.best_epoch > 0 and fit.coefficients['N_r'] != n_r   # it trained on
    parts = members(fit.net)
    assert len(parts) == 2 and fit.net.weights[1].shape == (10, 12)
    assert np.all(fit.net.weights[1][:5, 6:] == 0) and np.all(fit.net.weights[1][5:, :6] == 0)
    rng = np.random.default_rng(4)
    for _ in range(3):
        x = rng.normal(0, 1, 3 * N_FEATURES)
        assert np.allclose(_forward(fit.net, x), np.mean([_forward(m, x) for m in parts], 0),
                           rtol=1e-10, atol=1e-14)
    kept = train_residual(suzaku, trials[:4], coefficients=jc, start=start,
                          config=replace(cfg, significance=1e9))
    assert kept.best_epoch == 0 and kept.coefficients == {'N_r': n_r}
    assert any('the network it started from' in n for n in kept.notes)
    for _ in range(3):
        x = rng.normal(0, 2, 3 * N_FEATURES)
        assert np.allclose(_raw_forward(kept.net, x), _raw_forward(start, x), rtol=1e-9,
                           atol=1e-14)
    with pytest.raises(TuningError, match='window is 3 samples'):
        train_residual(suzaku, trials[:4], start=start, config=replace(cfg, window=4))
    with pytest.raises(TuningError, match="does not read the physics' accelerations"):
        train_residual(suzaku, trials[:4], start=start, config=replace(cfg, physics_input=True))


def test_a_network_reading_the_physics_trains_and_runs(suzaku, hidden_fit):
    """Training with physics_input end to end: 12 features, saved names, a finite run."""
    from mmg_tuner.learn import ResidualConfig, train_residual
    _, trials = hidden_fit
    fit = train_residual(suzaku, trials[:3], config=ResidualConfig(
        **{**CI, 'epochs': 2}, seed=0, significance=0.0, physics_input=True))
    net = fit.net
    assert net.physics_input and net.n_inputs == CI['window'] * (N_FEATURES + 3)
    assert net.x_std[N_FEATURES:].min() < 0.1   # standardised by the physics' spread
    assert fit.best_epoch > 0 and np.any(net.weights[-1] != 0)
    run = simulate_hybrid(suzaku, net, trials[4], restart_every_s=50.0)
    assert run.ok and np.all(np.isfinite(run.states))


def test_a_training_trial_without_its_group_is_refused_before_any_training(suzaku, hidden_fit,
                                                                           monkeypatch):
    from mmg_tuner.errors import TuningError
    from mmg_tuner.learn import _engine, ResidualConfig, train_residual
    _, trials = hidden_fit

    def never(*a, **k):
        raise AssertionError('the training started')
    monkeypatch.setattr(_engine, 'make_simulator', never)
    groups = {trials[1].name: 'a', trials[2].name: 'a'}   # trials[0] has none
    with pytest.raises(TuningError, match=re.escape(f'trial {trials[0].name!r} has no group')):
        train_residual(suzaku, trials[:2], validation=trials[2:3], groups=groups,
                       config=ResidualConfig(**{**CI, 'epochs': 1}))


# ------------------------------------------------------- balance and selection (kinds alike)
def test_window_weights_balance_trials_and_groups():
    from mmg_tuner.errors import TuningError
    from mmg_tuner.learn.train import window_weights
    names = ['long'] * 6 + ['short'] * 2 + ['other'] * 4
    groups = {'long': 'turning', 'short': 'zigzag', 'other': 'zigzag'}
    assert np.array_equal(window_weights(names, 'window'), np.ones(12))
    w = window_weights(names, 'trial')
    tot = {n: w[[i for i, m in enumerate(names) if m == n]].sum() for n in set(names)}
    assert tot['long'] == pytest.approx(tot['short']) == pytest.approx(tot['other'])
    w = window_weights(names, 'group', groups)
    assert w.mean() == pytest.approx(1.0)
    assert w[:6].sum() == pytest.approx(w[6:].sum())        # turning = zigzag
    assert w[6:8].sum() == pytest.approx(w[8:].sum())       # the zigzag trials alike
    with pytest.raises(TuningError, match='other'):
        window_weights(names, 'group', {'long': 'a', 'short': 'b'})


def test_every_group_selection_refuses_a_gain_bought_on_one_group():
    from mmg_tuner.learn.train import group_losses, selection_score
    labels = np.array(['a', 'a', 'b', 'b'])
    w = np.ones(4)
    phys = group_losses(np.ones(4), w, labels, ['a', 'b'])
    lopsided = np.array([0.2, 0.2, 1.2, 1.2])         # better on the mean, worse on b
    even = np.array([0.9, 0.9, 0.9, 0.9])
    g1, g2 = (group_losses(x, w, labels, ['a', 'b']) for x in (lopsided, even))
    assert selection_score('mean', 0.7, g1, phys) < selection_score('mean', 0.9, g2, phys)
    assert selection_score('every_group', 0.7, g1, phys) > 1.0     # the physics (1) stays
    assert selection_score('every_group', 0.9, g2, phys) == pytest.approx(0.9)
    # weights count within a group: a heavy window dominates its group's loss
    assert group_losses(lopsided, np.array([3.0, 1.0, 1.0, 1.0]), labels, ['a'])[0] == \
        pytest.approx(0.2)
    assert group_losses(np.array([0.0, 1.0]), np.array([3.0, 1.0]), labels[:2],
                        ['a'])[0] == pytest.approx(0.25)


def test_kept_network_beats_the_physics_on_every_group(suzaku, hidden_fit):
    from mmg_tuner.learn import ResidualConfig, train_residual
    _, trials = hidden_fit
    groups = {t.name: t.name.rstrip('+-0123456789') for t in trials[:4]}
    cfg = ResidualConfig(**{**CI, 'epochs': 15}, seed=0, balance='group', select='every_group')
    fit = train_residual(suzaku, trials[:4], groups=groups, config=cfg)
    assert set(fit.val_by_group) == set(groups.values()) == set(fit.share_by_group)
    assert all(0.0 <= s <= 1.0 for s in fit.share_by_group.values())
    if fit.best_epoch > 0:   # the rule: kept only when better on each group
        assert all(v['hybrid'] < v['physics'] for v in fit.val_by_group.values())
    else:
        assert all(v['hybrid'] == v['physics'] for v in fit.val_by_group.values())
    crit = [h['criterion'] for h in fit.history]
    assert crit[0] == 1.0 and fit.history[fit.best_epoch]['criterion'] == min(crit)
    from mmg_tuner.errors import TuningError
    with pytest.raises(TuningError, match='groups'):
        train_residual(suzaku, trials[:4], config=cfg)


def _forward(net, x):
    from mmg_tuner.learn.residual import mlp_forward
    sizes, flat = net.packed()
    n = int(sizes.max())
    return mlp_forward(sizes, flat, x, np.empty(n), np.empty(n))[:3].copy()


def test_ensemble_is_the_mean_of_its_members():
    from mmg_tuner.learn import ensemble
    nets = [random_net(hidden=(8, 6), seed=s) for s in (1, 2, 3)]
    nets = [replace(n, x_mean=nets[0].x_mean, x_std=nets[0].x_std) for n in nets]
    ens = ensemble(nets)
    assert [w.shape for w in ens.weights] == [(24, 3 * N_FEATURES), (18, 24), (3, 18)]
    rng = np.random.default_rng(0)
    for _ in range(5):
        x = rng.normal(0, 1, 3 * N_FEATURES)
        want = np.mean([_forward(n, x) for n in nets], axis=0)
        assert np.allclose(_forward(ens, x), want, rtol=1e-12, atol=1e-15)
    assert ens.meta['ensemble_of_seeds'] == [1, 2, 3]
    with pytest.raises(ConfigError, match='network 1'):
        ensemble([nets[0], random_net(hidden=(8, 5), seed=5)])   # other hidden sizes


# ------------------------------------------------------------------- blends of hybrid and pure
def _raw_forward(net, x_raw):
    """Return the net's accelerations [m/s^2, rad/s^2] for an unstandardised window."""
    z = (x_raw - np.tile(net.x_mean, net.window)) / np.tile(net.x_std, net.window)
    return _forward(net, z) * net.y_scale


def test_restandardised_gives_the_same_accelerations():
    """
    A network rewritten in other scales gives the same accelerations.

    A wrong shift, gain or output scale changes them by the scales' ratio (order one).
    """
    from mmg_tuner.learn.train import restandardised
    net = random_net(hidden=(8, 6), seed=1)
    other = random_net(hidden=(8, 6), seed=2)
    moved = restandardised(net, other.x_mean, other.x_std, np.array([2e-3, 5e-4, 1e-4]))
    rng = np.random.default_rng(3)
    for _ in range(5):
        x = rng.normal(0, 2, 3 * N_FEATURES)
        assert np.allclose(_raw_forward(moved, x), _raw_forward(net, x), rtol=1e-10,
                           atol=1e-15)


def test_a_blend_steps_as_the_mean_of_its_hybrid_and_pure_members(suzaku, trial, tmp_path):
    """
    An ensemble of two hybrid and one pure network is one model: physics weight 2/3.

    One Euler step of the blend from each measured state equals the mean of its members'
    steps (each member with its own physics flag and standardisation); a blend that added the
    whole physics, or none, misses by the physics' acceleration x dt. The weight survives the
    file (format 2) and members() gives each member back with its own flag.
    """
    from mmg_tuner.learn import ensemble
    from mmg_tuner.learn.residual import FORMAT_BLEND
    from mmg_tuner.learn.model import Model
    from mmg_tuner.learn.train import members
    nets = [random_net(window=3, hidden=(8, 6), scale=1e-3, seed=s, physics=s != 3)
            for s in (1, 2, 3)]
    blend = ensemble(nets)
    assert blend.physics == pytest.approx(2 / 3)
    assert Model(suzaku, blend).kind == 'blend'
    short = trial.slice(0.0, 40.0)
    step = 2 * float(trial.dt)   # restarts every 2 samples: each odd sample is one step

    def one_steps(net):
        return simulate_segments(suzaku, net, short, 'euler', restart_every_s=step)[0]

    got = one_steps(blend)
    want = np.mean([one_steps(n) for n in nets], axis=0)
    assert np.allclose(got, want, rtol=0, atol=1e-9), np.abs(got - want).max()
    physics_only = one_steps(None)
    assert np.abs(got[1::2, 3:] - physics_only[1::2, 3:]).max() > 1e-4   # the nets matter
    path = tmp_path / 'blend.npz'
    blend.save(path)
    back = ResidualNet.load(path)
    with np.load(path) as z:
        assert str(z['format']) == FORMAT_BLEND
    assert back.physics == pytest.approx(2 / 3)
    assert [m.physics for m in members(back)] == [1.0, 1.0, 0.0]
    assert np.allclose(one_steps(members(back)[2]), one_steps(nets[2]), rtol=0, atol=1e-9)


# ------------------------------------------------------------- every family, by its channels
FAMILY_SHIPS = {'container': 'suzaku', 'standard': 'kvlcc2', 'lowspeed': 'esso_osaka_3m',
                'surge_decoupled_rudder': 'esso_osaka_3m_control',
                'surge_decoupled': 'qiuxin_tug', 'simplified6': 'qiuxin_tug_simplified6'}


def test_the_family_ships_cover_every_family():
    from mmg_tuner.core.models import families
    assert set(FAMILY_SHIPS) == {f.name for f in families()}


def sailed(ship, T=121, dt=0.2):
    """
    Sail ``ship`` without noise under smooth commands of every always-recorded channel.

    At 5 Hz: the simplified6 tug's explicit RK4 diverges at 2 Hz (a stiff model; its
    catalogue records at 5 Hz).
    """
    from mmg_tuner.core.channels import TABLE
    from mmg_tuner.core.limits import input_limits
    from mmg_tuner.core.simulate import self_propulsion_rpm
    lim = input_limits(ship)
    t = np.arange(T) * dt
    wave = np.sin(2 * np.pi * t / 40.0)
    u0 = 0.2 * lim.top_speed_ms
    inputs = {}
    for c in ship.family.inputs:
        d, limit = TABLE[c].default, lim.channels[c].limit
        if d is not None and d != d:
            continue   # a channel recorded only sometimes: NaN
        if c == 'rpm':
            inputs[c] = np.full(T, self_propulsion_rpm(ship, u0))
        elif TABLE[c].unit == 'rev/s':   # a drive ahead, a tunnel thruster about zero
            inputs[c] = 0.3 * limit * (wave if d == 0.0 else 1.0 + 0.2 * wave)
        else:
            inputs[c] = 0.5 * min(limit, 0.5) * wave
    from mmg_tuner.core.simulate import simulate
    run = simulate(ship, [0.0, 0.0, 0.0, u0, 0.0, 0.0], inputs, dt, 'rk4')
    assert run.ok, (ship.name, run.status)
    return run


@pytest.mark.parametrize('family,physics_input,physics',
                         [(f, False, True) for f in sorted(FAMILY_SHIPS)]
                         + [(f, True, True) for f in sorted(FAMILY_SHIPS)]
                         + [('container', True, False)])
def test_training_simulation_equals_inference_for_every_family(family, physics_input, physics):
    """
    The JAX window simulation equals the compiled hybrid run for every family (1e-12).

    A network of the family's features (its first channels by name: a tug's shaft speeds
    and azimuths; with physics_input, the physics' accelerations) with a current and an
    antenna offset, restarted at the same sample; a pure network reading the physics too.
    """
    pytest.importorskip('jax')
    import equinox as eqx
    import jax
    import jax.numpy as jnp

    from mmg_tuner.core.correction import feature_names
    from mmg_tuner.learn._engine import make_simulator, MLP
    ship = load_ship(FAMILY_SHIPS[family]).with_params(
        {'antenna_x': 0.3, 'current_speed': 0.05, 'current_dir': 1.0})
    trial = sailed(ship)
    names = feature_names(ship.family, physics_input)
    assert names[3:3 + min(4, len(ship.family.inputs))] == ship.family.inputs[:4]
    net = replace(random_net(dt=trial.dt, scale=1e-3 if physics else 0.3,
                             physics_input=physics_input, physics=physics), features=names)
    k0, H = 40, 20
    model = MLP([net.n_inputs, 8, 3], jax.random.PRNGKey(0))
    model = eqx.tree_at(lambda m: [la.weight for la in m.layers] + [la.bias for la in m.layers],
                        model, [jnp.asarray(x) for x in net.weights + net.biases])
    sim = make_simulator(ship.kind, ship.params, physics, True, trial.dt, net.x_mean,
                         net.x_std, net.y_scale, physics_input=physics_input)
    b = _window_batch(ship, trial, net, k0, H)
    obs, res = sim(model, b['x0'], b['hist'], b['inp'], b['act'], b['wind'])
    ref, _, _, _ = simulate_segments(ship, net, trial, 'rk4', k0 * trial.dt)
    assert np.max(np.abs(np.asarray(res))) > 1e-5   # the network acts
    # measured 2026-11-29: at most 3.6e-15 m apart (the same kernel, JAX's own kinematics)
    np.testing.assert_allclose(np.asarray(obs)[0], ref[k0 + 1:k0 + H + 1], rtol=1e-12,
                               atol=1e-12)


def test_a_network_trained_for_another_family_is_refused():
    tug, suzaku = load_ship('qiuxin_tug'), load_ship('suzaku')
    from mmg_tuner.core.correction import feature_names
    from mmg_tuner.core.stepper import ShipSimulator
    from mmg_tuner.learn.residual import check_fits
    net = replace(random_net(dt=0.5), features=feature_names(tug.family))
    check_fits(net, tug)
    with pytest.raises(ConfigError, match='n_port.*suzaku.*rpm, rudder'):
        check_fits(net, suzaku)
    with pytest.raises(SimulationError, match='n_port'):
        ShipSimulator(suzaku, dt=0.5, x0=[0, 0, 0, 3.0, 0, 0], rpm=106.0, residual=net)
    sim = ShipSimulator(tug, dt=0.5, x0=[0, 0, 0, 1.0, 0, 0], residual=net)
    sim.set_command('n_port', 6.0)
    sim.set_command('n_stbd', 6.0)
    assert sim.step(20) and np.all(np.isfinite(sim.s))


def test_a_tug_hybrid_trains_saves_and_drives_the_node_stepper(tmp_path):
    """
    Train, save and run the hybrid of a craft without a screw and rudder, end to end.

    Trained through the JAX simulation on the tug's catalogue (a thrust scale the physics
    lacks), its features the tug's channels by name, saved and loaded, run by
    ``simulate_hybrid`` and the stepper.
    """
    pytest.importorskip('jax')
    from mmg_tuner.core.actuators import twin_azimuth_trials as twin
    from mmg_tuner.core.stepper import ShipSimulator
    from mmg_tuner.learn import ResidualConfig, train_residual

    tug = load_ship('qiuxin_tug')
    truth = tug.with_params({'thrust_scale_port': 0.8})
    cat = {m.name: m for m in twin.catalogue(tug)}
    trials = [twin.generate(truth, cat[n], 2.5, twin.Noise(), i)[1]
              for i, n in enumerate(('zigzag_p20deg_7rps', 'turning_p20deg_7rps',
                                     'differential_1'))]
    fit = train_residual(tug, trials, config=ResidualConfig(
        window=2, hidden=(8,), horizon_s=10.0, epochs=5, patience=5, seed=0))
    net = fit.net
    assert net.features[3:7] == ('n_port', 'n_stbd', 'azimuth_port', 'azimuth_stbd')
    net.save(tmp_path / 'tug.npz')
    back = ResidualNet.load(tmp_path / 'tug.npz')
    assert back.features == net.features
    run = simulate_hybrid(tug, back, trials[0])
    assert run.ok and np.all(np.isfinite(run.states))
    sim = ShipSimulator(tug, dt=0.4, x0=[0, 0, 0, 1.0, 0, 0], residual=back)
    sim.set_command('n_port', 7.0)
    sim.set_command('n_stbd', 7.0)
    assert sim.step(50) and np.all(np.isfinite(sim.s))


def test_the_stepper_feeds_a_tug_network_its_commands_by_name():
    """The node's stepper hands the network the tug's channels (not a screw's rpm/rudder)."""
    from mmg_tuner.core.correction import feature_names
    from mmg_tuner.core.stepper import ShipSimulator
    tug = load_ship('qiuxin_tug')
    seen = []

    class Spy:   # the stepper's view of a network: dt_s, physics, features, stepper()
        dt_s, physics, features = 0.4, 1.0, feature_names(tug.family)

        def stepper(self):
            return self

        def reset(self, state=None):
            pass

        def accelerations(self, state, act, wind):
            seen.append(tuple(act))
            return 0.0, 0.0, 0.0

    sim = ShipSimulator(tug, dt=0.4, x0=[0, 0, 0, 1.0, 0, 0], residual=Spy())
    for channel, value in (('n_port', 7.0), ('n_stbd', 6.0), ('azimuth_port', 0.3)):
        assert sim.set_command(channel, value) == ''
    assert sim.step(2)
    assert seen[-1] == (7.0, 6.0, 0.3, 0.0)
