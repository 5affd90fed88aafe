"""
Contracts every registry entry must meet, the frames module and the numba cache key.

Contracts every registry entry must meet (effects, model families), the frames module and the numba
cache key: the way SciPy's solvers or pysindy's libraries are tested.
"""
import math
import os
from pathlib import Path
import shutil
import subprocess
import sys

from mmg_tuner.core import frames
from mmg_tuner.core.actuators import REGISTRY as ACTUATOR_REGISTRY
from mmg_tuner.core.channels import TABLE
from mmg_tuner.core.effects import describe_values, EFFECTS
from mmg_tuner.core.layout import EFFECT_NEUTRAL, PARAM_INDEX, SHARED_PARAMS
from mmg_tuner.core.models import declared_params, families, REGISTRY
from mmg_tuner.core.ship import load_ship
from mmg_tuner.core.simulate import simulate
import numpy as np
import pytest


def _run(ship, u0, rpm):
    T = 200
    ctrl = np.column_stack([np.full(T, rpm), np.radians(20 * np.sin(np.arange(T) / 15))])
    return simulate(ship, [0, 0, 0, u0, 0, 0], ctrl, 0.5, 'rk4')


@pytest.mark.parametrize('name', list(EFFECTS))
def test_effect_entry_contract(name, suzaku, kvlcc2):
    e = EFFECTS[name]
    assert len(set(e.params)) == len(e.params) and all(p in PARAM_INDEX for p in e.params)
    for ship in (suzaku, kvlcc2):
        for p, n, (lo, hi), s, per in zip(e.params, e.neutral, e.bounds(ship),
                                          e.smallest_for(ship), e.periodic):
            assert EFFECT_NEUTRAL[p] == n
            assert lo <= n <= hi and lo < hi, (name, p)
            assert n + s <= hi or n - s >= lo, (name, p)   # the smallest size fits the box
            if per:
                assert (lo, hi) == (-math.pi, math.pi) and s == 0
    # Froude scaling: a model's box is the full-scale box scaled (speeds/times 1/sqrt, m 1/r)
    for (lo, hi), (klo, khi), u in zip(e.bounds(suzaku), e.bounds(kvlcc2), e.units):
        if u in ('m/s', 's'):
            assert khi == pytest.approx(hi / math.sqrt(kvlcc2.scale_ratio))
    assert not e.actuator or e.actuator in ACTUATOR_REGISTRY
    if e.actuator == 'twin_azimuth':   # only a family with that actuator shows it
        _twin_effect_hook_exists(e)
    # neutral values make the effect vanish: the same trajectory as the plain model
    for ship, u0, rpm in ((suzaku, 3.0, 106.0), (kvlcc2, 1.18, 711.0)):
        plain = _run(ship, u0, rpm)
        assert np.array_equal(_run(ship.with_params(e.neutral_values), u0, rpm).states,
                              plain.states)
        if e.actuator and e.actuator not in ship.family.actuators:
            continue
        # and a value off neutral changes it (the kernel hook exists)
        (lo, hi), = e.bounds(ship)[:1]
        off = {e.params[0]: e.neutral[0] + 0.5 * (hi - e.neutral[0])}
        if name == 'wind':
            off = {'wind_speed': 10.0 / math.sqrt(ship.scale_ratio), 'wind_dir': 1.0}
        if name == 'wind' and not ship.has_windage:
            continue
        if name == 'current':
            off['current_dir'] = 1.0
        assert not np.allclose(_run(ship.with_params(off), u0, rpm).states, plain.states), name
    text = describe_values(e, dict(zip(e.params, e.neutral)),
                           dict(zip(e.params, [0.1] * len(e.params))))
    assert isinstance(text, str) and text and '±' in text


def _twin_effect_hook_exists(e):
    """Check that a twin_azimuth effect vanishes at neutral and acts off it, on the tug."""
    ship = load_ship('qiuxin_tug')
    T = 300
    ctrl = {'n_port': np.full(T, 8.0), 'n_stbd': np.full(T, 6.0),
            'azimuth_port': np.radians(20 * np.sin(np.arange(T) / 15)),
            'azimuth_stbd': np.radians(20 * np.sin(np.arange(T) / 15))}

    def run(s):
        return simulate(s, [0, 0, 0, 1.0, 0, 0], ctrl, 0.2, 'rk4').states

    plain = run(ship)
    assert np.array_equal(run(ship.with_params(e.neutral_values)), plain)
    (lo, hi), = e.bounds(ship)[:1]
    off = {e.params[0]: e.neutral[0] + 0.5 * (lo - e.neutral[0])}
    assert not np.allclose(run(ship.with_params(off)), plain), e.name


def test_effect_boxes_scale_with_the_ship(suzaku, kvlcc2):
    """
    Every speed and time box shrinks with Froude scaling, the current's included.

    (it was a fixed 1.5 m/s).
    """
    assert EFFECTS['current'].bounds(suzaku)[0] == (0.0, 1.5)
    assert EFFECTS['current'].bounds(kvlcc2)[0][1] == pytest.approx(
        1.5 / math.sqrt(kvlcc2.scale_ratio))
    assert EFFECTS['rudder_lag'].bounds(kvlcc2)[0][1] < 20.0 / 6


@pytest.mark.parametrize('fam', families(), ids=lambda f: f.name)
def test_family_contract(fam):
    assert fam.name == REGISTRY[fam.code] and fam.params == declared_params(fam.name)
    assert set(fam.channels) <= set(TABLE)
    assert fam.inputs[:2] == ('rpm', 'rudder') or 'screw_rudder' not in fam.actuators
    assert all(p in PARAM_INDEX for p in fam.params + tuple(fam.defaults))
    assert all(k in PARAM_INDEX for k in fam.required)
    assert not set(fam.params) & set(SHARED_PARAMS)
    assert isinstance(fam.astern_rpm, bool) and isinstance(fam.astern_surge, bool)
    assert isinstance(fam.air_drag, bool) and (fam.wind is None or callable(fam.wind))
    assert fam.description
    # a ship config of the family loads and runs through the generic kernels, batched ==
    # single to the bit, with the inputs the family reads (thrusters left out = 0 rev/s)
    from mmg_tuner.core.ship import config_dirs, load_ship
    from mmg_tuner.core.simulate import simulate_batch
    import yaml
    cfgs = sorted(p for d in config_dirs() for p in d.glob('*.yaml')
                  if (yaml.safe_load(p.read_text()) or {}).get('model') == fam.name)
    assert cfgs, f'no ship config with model: {fam.name}'
    ship = load_ship(cfgs[0])
    lim_u = 0.5 * math.sqrt(9.81 * ship.L_pp) * 0.3
    T = 100
    sub = 1
    if 'rpm' in fam.inputs:
        ctrl = np.column_stack([np.full(T, 60.0 * 10 if fam.name == 'lowspeed' else 0.0),
                                np.radians(20 * np.sin(np.arange(T) / 15))])
        if fam.name != 'lowspeed':
            from mmg_tuner.core.simulate import self_propulsion_rpm
            ctrl[:, 0] = self_propulsion_rpm(ship, lim_u)
    else:   # another actuator: its required channels, angles swinging, speeds held
        from mmg_tuner.core.simulate import kernel_inputs
        ctrl = kernel_inputs(fam, {c: np.radians(20 * np.sin(np.arange(T) / 15))
                                   if TABLE[c].unit == 'rad' else np.full(T, 5.0)
                                   for c in fam.inputs if TABLE[c].default is None})
        sub = 8   # a stiff control-oriented model (simplified6's Table 4) needs finer steps
    x0 = np.array([0, 0, 0, lim_u, 0, 0])
    one = simulate(ship, x0, ctrl, 0.2 * ship.L_pp / lim_u, 'rk4', substeps=sub)
    assert one.ok
    many, status, _ = simulate_batch(ship.kind, ship.params[None], x0[None], ctrl[None],
                                     0.2 * ship.L_pp / lim_u, integrator='rk4', substeps=sub)
    assert np.array_equal(many[0, 0], one.states) and status[0, 0] == 0


def test_status_checks_follow_the_family(suzaku):
    """
    A family without astern capability stops at rpm <= 0 and u <= 0.

    (the per-family flags the kernels read).
    """
    assert not suzaku.family.astern_rpm and not suzaku.family.astern_surge
    from mmg_tuner.core.actuators.screw_rudder import rpm_status
    from mmg_tuner.core.layout import OK, RPM_NOT_POSITIVE
    astern = suzaku.family.astern_rpm
    assert rpm_status(-1.0, astern) == RPM_NOT_POSITIVE
    assert rpm_status(float('nan'), astern) == RPM_NOT_POSITIVE
    assert rpm_status(1.0, astern) == OK


def test_non_finite_state_is_caught_inside_the_inlined_step(suzaku):
    """
    The finite-state check, inlined into fast-math kernels, still sees an overflow.

    (R_0 = -1e300 pushes u past the largest float within two steps; the run must stop there
    as diverged, not run on with u = inf or report ok.)
    """
    p = suzaku.params.copy()
    p[PARAM_INDEX['R_0']] = -1e300
    ctrl = np.tile([106.0, math.radians(10.0)], (20, 1))
    for integrator in ('euler', 'rk4'):
        run = simulate(suzaku, [0, 0, 0, 3.086, 0, 0], ctrl, 1.0, integrator, params=p)
        assert run.status == 'diverged (non-finite state)'
        k = int(round(run.fail_time_s))
        assert 1 <= k <= 2
        assert np.isnan(run.states[k:]).all() and np.isfinite(run.states[:k]).all()


def test_simulate_returns_the_one_trial_type(suzaku):
    from mmg_tuner.data.trial import Trial
    T = 50
    ctrl = np.column_stack([np.full(T, 106.0), np.zeros(T), np.full(T, 3.0), np.full(T, -4.0)])
    tr = simulate(suzaku, [0, 0, 0, 3.0, 0, 0], ctrl, 1.0)
    assert isinstance(tr, Trial) and tr.ok and tr.status == 'ok' and tr.fail_time_s is None
    assert tr.controls.shape == (T, 2) and tr.wind.shape == (T, 2)
    assert np.array_equal(tr.input_array(suzaku.family.channels), ctrl)
    assert np.array_equal(tr['wind_e'], ctrl[:, 3])


def test_frames_round_trips_and_conventions():
    rng = np.random.default_rng(0)
    yaw = rng.uniform(-10, 10, 50)
    q = frames.quaternion_from_yaw(yaw)
    assert np.allclose(frames.wrap_angle(frames.yaw_from_quaternion(*q) - yaw), 0, atol=1e-12)
    # ENU yaw 0 (facing east) is psi = 90 deg; facing north (yaw 90 deg) is psi = 0
    assert frames.enu_yaw_to_psi(0.0) == pytest.approx(math.pi / 2)
    assert frames.enu_yaw_to_psi(math.pi / 2) == pytest.approx(0.0)
    assert frames.psi_to_enu_yaw(frames.enu_yaw_to_psi(0.3)) == pytest.approx(0.3)
    assert frames.enu_to_mmg_position(1.0, 2.0) == (2.0, 1.0)   # east 1, north 2
    assert frames.mmg_body_to_flu(*frames.flu_to_mmg_body(1.0, 2.0, 3.0)) == (1.0, 2.0, 3.0)
    # body <-> north/east at psi = 90 deg: forward is east, starboard is south
    n, e = frames.body_to_ne(math.pi / 2, 1.0, 0.0)
    assert (n, e) == pytest.approx((0.0, 1.0))
    n, e = frames.body_to_ne(math.pi / 2, 0.0, 1.0)
    assert (n, e) == pytest.approx((-1.0, 0.0))
    f, s = frames.ne_to_body(0.7, *frames.body_to_ne(0.7, 2.0, -1.0))
    assert (f, s) == pytest.approx((2.0, -1.0))
    for a in (-7.0, -math.pi, -1.0, 0.0, 3.0, math.pi, 4.0, 100.0):
        w = frames.wrap_pi(a)
        assert -math.pi <= w <= math.pi and math.isclose(math.cos(w), math.cos(a), abs_tol=1e-9)
        assert w == pytest.approx(float(frames.wrap_angle(a))) or abs(w) == pytest.approx(math.pi)
    psi = np.cumsum(np.full(100, 0.3))
    assert np.allclose(frames.unwrap(frames.wrap_angle(psi)), psi)


def test_the_numba_cache_folder_changes_with_any_core_source(tmp_path):
    """
    The numba cache's folder is named by a hash of every core source, not the kernel's file.

    numba alone invalidates a kernel when its own file changes; a family's capability flag
    read by the kernels lives in another file. The slow test below runs the stale-kernel case
    end to end (two full compiles).
    """
    import numba

    from mmg_tuner.core import _numba_cache
    import mmg_tuner.core.integrate  # noqa: F401  (configures the cache before compiling)
    assert numba.config.CACHE_DIR == str(_numba_cache.cache_dir())
    assert _numba_cache.source_hash()[:16] in numba.config.CACHE_DIR
    core = tmp_path / 'core'
    shutil.copytree(_numba_cache.CORE_DIR, core,
                    ignore=shutil.ignore_patterns('__pycache__', '*.pyc'))
    before = _numba_cache.source_hash(core)
    assert before == _numba_cache.source_hash()
    fam = core / 'models' / 'container.py'
    fam.write_text(fam.read_text().replace('ASTERN_RPM = False', 'ASTERN_RPM = True'))
    assert _numba_cache.source_hash(core) != before


@pytest.mark.slow
def test_numba_cache_is_keyed_by_the_core_sources(tmp_path):
    """
    A change to a module a kernel imports must not run the stale cached kernel.

    A change to a module a kernel imports (here a family's capability flag, read by
    the kernels) must not run the stale cached kernel: numba alone would, since integrate.py
    did not change.
    """
    pkg = Path(__file__).resolve().parents[2] / 'mmg_tuner'
    shutil.copytree(pkg, tmp_path / 'mmg_tuner',
                    ignore=shutil.ignore_patterns('__pycache__', '*.pyc'))
    env = {**os.environ, 'NUMBA_CACHE_DIR': str(tmp_path / 'cache'),
           'PYTHONPATH': str(tmp_path)}
    code = ('import numba, numpy as np; from mmg_tuner.core.integrate import simulate_one; '
            'out = np.empty((3, 6)); '
            'ctrl = np.array([[-60.0, 0.0, np.nan, np.nan]] * 3); '
            'st, _ = simulate_one(0, np.load("p.npy"), np.array([0, 0, 0, 1.0, 0, 0]), ctrl, 3, '
            '0.1, 1, 0, out); print(st, numba.config.CACHE_DIR)')
    from mmg_tuner.core.ship import load_ship
    np.save(tmp_path / 'p.npy', load_ship('suzaku').params)

    def run():
        out = subprocess.run([sys.executable, '-c', code], env=env, cwd=tmp_path,
                             capture_output=True, text=True, check=True).stdout.split()
        return int(out[0]), out[1]

    status, d1 = run()
    assert status == 3 and d1.startswith(str(tmp_path / 'cache'))
    fam = tmp_path / 'mmg_tuner' / 'core' / 'models' / 'container.py'
    fam.write_text(fam.read_text().replace('ASTERN_RPM = False', 'ASTERN_RPM = True'))
    status, d2 = run()
    assert status == 0 and d2 != d1
