"""
The kernels compiled for one family (called with its tag).

The entry points in ``core/integrate.py`` turn ``ship.kind`` into the family's tag, so each
family runs kernels compiled for it alone (its forces, actuators and equations of motion); a
tag must select its own family (a tag mapped to the wrong forces would pass a test that only
compares a family with itself, not this one).
"""
from mmg_tuner.core import dynamics, integrate
from mmg_tuner.core.channels import TABLE
from mmg_tuner.core.layout import OK, PARAM_INDEX
from mmg_tuner.core.models import REGISTRY
from mmg_tuner.core.ship import config_dirs, load_ship
from mmg_tuner.core.simulate import self_propulsion_rpm, simulate
from mmg_tuner.core.trial import input_array
import numpy as np
import pytest


def _ships_by_family():
    ships = {}
    for d in config_dirs():
        for f in sorted(d.glob('*.yaml')):
            try:
                ship = load_ship(f)
            except Exception:  # noqa: BLE001  (topic maps, node parameters: not ships)
                continue
            ships.setdefault(ship.model, ship)
    return ships


SHIPS = _ships_by_family()


def _state(ship, rng):
    u = _speed(ship)
    return np.array([1.0, -2.0, rng.uniform(-3, 3), u * rng.uniform(0.5, 1.5),
                     u * rng.uniform(-0.1, 0.1), rng.uniform(-0.3, 0.3) * u / ship.L_pp])


def _speed(ship):
    return 0.1 * (9.81 * ship.L_pp) ** 0.5   # Froude number 0.1 [m/s]


@pytest.mark.parametrize('name', REGISTRY)
def test_every_family_has_a_ship_to_check_it_with(name):
    assert name in SHIPS, f'no ship YAML under config/ uses model family {name!r}'


@pytest.mark.parametrize('name', REGISTRY)
def test_tagged_derivative_equals_the_run_time_branch(name):
    ship = SHIPS[name]
    tag = dynamics.family_tag(ship.kind)
    rng = np.random.default_rng(7)
    p = ship.params.copy()
    a = np.empty(6)
    b = np.empty(6)
    for k in range(100):
        p[PARAM_INDEX['wind_speed']] = rng.uniform(0, 8) if k % 2 else 0.0
        p[PARAM_INDEX['wind_dir']] = rng.uniform(-3, 3)
        s = _state(ship, rng)
        act = (rng.uniform(2, 15), rng.uniform(-0.6, 0.6), rng.uniform(-5, 5),
               rng.uniform(-5, 5))[:len(ship.family.outputs)]
        dynamics.derivative(tag, p, s, act, a)
        dynamics.derivative(tag, p, s, act, b)
        assert np.array_equal(a, b) and np.all(np.isfinite(a))
        # the tag's forces are its own family's, not another's
        forces = dynamics.family_forces(tag, p, s[3], s[4], s[5], act)
        assert forces == pytest.approx(ship.family.forces(p, s[3], s[4], s[5], act), rel=1e-12)
    astern = np.array([0.0, 0.0, 0.0, -0.1, 0.0, 0.0])
    assert (integrate.state_status(tag, astern) == OK) == ship.family.astern_surge
    ctrl = np.tile([-60.0, 0.0] + [0.0] * (len(ship.family.inputs) - 2), (3, 1))
    run = simulate(ship, _state(ship, rng), ctrl, 0.5, check=False)
    assert run.ok == ship.family.astern_rpm   # rpm <= 0 stops a family without astern


def test_kernels_take_the_family_tag_only(suzaku):
    """The compiled kernels take the tag (one way); the Python entry points the code."""
    from numba.core.errors import TypingError
    with pytest.raises((TypeError, TypingError), match='FAMILY_TAGS'):
        dynamics.derivative(suzaku.kind, suzaku.params, np.ones(6), (1.0, 0.0), np.empty(6))


# One family per kind of actuator set (a screw and rudder; with tunnel thrusters and astern;
# twin azimuths): the dispatch from code to tag is one code path for all, and each family
# compiles its two private kernels anew here (35-50 s each on the CI machine), which the
# suite's 20 minutes cannot hold for all six.
DISPATCH_FAMILIES = ('container', 'lowspeed', 'surge_decoupled')


def test_the_dispatch_families_are_registered():
    assert set(DISPATCH_FAMILIES) <= set(REGISTRY) and set(DISPATCH_FAMILIES) <= set(SHIPS)


@pytest.mark.parametrize('name', DISPATCH_FAMILIES)
def test_entry_points_run_the_family_kernel(name):
    """simulate_many and cost_many (family code in, tag inside) equal the run-time branch."""
    ship = SHIPS[name]
    rng = np.random.default_rng(3)
    T, N, dt = 120, 3, 0.5
    x0 = _state(ship, rng)
    x0[2] = 0.0
    swing = np.radians(20) * np.sin(np.arange(T) / 10)
    cmds = {'wind_n': np.full(T, 3.0), 'wind_e': np.full(T, -2.0),
            'bow_thruster': np.full(T, 2.0), 'stern_thruster': np.full(T, -1.0)}
    if 'rpm' in ship.family.inputs:
        cmds.update(rpm=np.full(T, self_propulsion_rpm(ship, _speed(ship))), rudder=swing)
    else:   # another actuator: its own channels, angles swinging, speeds held
        cmds.update({c: swing if TABLE[c].unit == 'rad' else np.full(T, 3.0)
                     for c in ship.family.inputs if TABLE[c].default is None})
    ctrl = input_array(ship.family.channels, cmds, T)
    ctrls = np.stack([ctrl, ctrl[::-1].copy()])
    x0s = np.stack([x0, x0])
    lengths = np.array([T, T - 30])
    params = np.tile(ship.params, (N, 1)) * rng.uniform(0.95, 1.05, (N, len(ship.params)))
    params[:, PARAM_INDEX['time_offset']] = [0.0, 0.6, 0.0]
    outs = []
    for kernel, kind in ((integrate.simulate_many, ship.kind),
                         (integrate._simulate_many, dynamics.family_tag(ship.kind))):
        out = np.full((N, 2, T, 6), np.nan)
        st = np.zeros((N, 2), np.int64)
        kf = np.zeros((N, 2), np.int64)
        kernel(kind, params, x0s, ctrls, lengths, dt, 2, 1, out, st, kf)
        outs.append((out, st, kf))
    (o1, s1, k1), (o2, s2, k2) = outs
    assert np.array_equal(s1, s2) and np.array_equal(k1, k2)
    assert np.isfinite(o1[:, 0, :k1.min()]).all()
    np.testing.assert_allclose(o1, o2, rtol=1e-9, atol=1e-9)

    w = np.array([1.0, 1.0, 5.0, 0.5, 0.5, 20.0])
    meas = o1[0].copy()
    meas[np.isnan(meas)] = 0.0
    Js = []
    for kernel, kind in ((integrate.cost_many, ship.kind),
                         (integrate._cost_many, dynamics.family_tag(ship.kind))):
        J = np.empty((N, 2))
        kf = np.empty((N, 2), np.int64)
        kernel(kind, params, meas, ctrls, lengths, dt, 1, 0, w, 20, J, kf)
        Js.append((J, kf))
    assert np.array_equal(Js[0][1], Js[1][1])
    np.testing.assert_allclose(Js[0][0], Js[1][0], rtol=1e-9)


def test_family_tag_refuses_unknown_codes():
    assert dynamics.family_tag(0) == dynamics.FAMILY_TAGS[0]
    for bad in (-1, len(REGISTRY)):
        with pytest.raises(ValueError, match='no model family with code'):
            dynamics.family_tag(bad)
    with pytest.raises(ValueError, match='no model family with code'):
        integrate.cost_many(-1, None, None, None, None, 1.0, 1, 0, None, 0, None, None)
