"""
Issue 45's unit and model checks where every command and the API meet them.

- rpm logged as rev/s: named by the one trial-loading path (``api.load_trials``: tune,
  evaluate, diagnose, the fleet) as a WARNING, an error under ``--strict``; silent on a clean
  log and without a ship.
- the plausibility tolerances read through the one safe YAML reader (``_limits.load_yaml``).
- the API's simulate/evaluate refuse an impossible model in memory (``with_params``) with one
  line, and warn once on an implausible one.
- a network's response to full rudder each way (``learn/plausibility.py``): the wrong way or
  too fast is a WARNING at load, at the API and in the node's ``model plausibility`` status.
"""
import logging

import mmg_tuner as mt
from mmg_tuner import _limits
from mmg_tuner.cli.common import run_command
from mmg_tuner.cli.evaluate import command as evaluate_command
from mmg_tuner.cli.generate import approach
from mmg_tuner.core import plausibility
from mmg_tuner.core.trial import Trial
from mmg_tuner.data.csv_io import csv_text
from mmg_tuner.data.generate import generate_trial, SensorNoise
from mmg_tuner.errors import ConfigError, TrialDataError
from mmg_tuner.learn.plausibility import network_checked, network_findings
from mmg_tuner.learn.residual import FEATURES, N_FEATURES, ResidualNet, zero_net
import numpy as np
import pytest
import yaml


def _warnings(caplog, text):
    return [r.getMessage() for r in caplog.records
            if r.levelno == logging.WARNING and text in r.getMessage()]


# ---------------------------------------------------------------------- rpm or rev/s
@pytest.fixture(scope='module')
def logs(suzaku, tmp_path_factory):
    """Write a clean SUZAKU zigzag log (200 s at 10 Hz, 20 s approach) and one in rev/s."""
    rpm, speed, _ = approach(suzaku, None, None)
    tr = generate_trial(suzaku, 'zigzag', 20, None, rpm, speed, 200.0, 10.0, SensorNoise(), 5,
                        'zz', approach_s=20.0)[1]
    d = tmp_path_factory.mktemp('rps')
    (d / 'clean').mkdir()
    (d / 'rps').mkdir()
    (d / 'clean' / 'zz.csv').write_text(csv_text(tr.t, tr.states, tr.controls))
    (d / 'rps' / 'zz.csv').write_text(csv_text(tr.t, tr.states, tr.controls * [1 / 60, 1.0]))
    return d / 'clean', d / 'rps'


def test_rpm_as_rev_per_s_is_named_by_every_loading_command(suzaku, logs, caplog):
    clean, rps = logs
    with caplog.at_level(logging.WARNING):
        mt.load_trials(clean, ship=suzaku)
        mt.load_trials(rps)                      # no ship: no balance to judge by
    assert not _warnings(caplog, 'rev/s')
    with caplog.at_level(logging.WARNING):
        mt.load_trials(rps, ship=suzaku)
    (w,) = _warnings(caplog, 'looks like rev/s')
    assert w.startswith("WARNING: zz: channel 'rpm'") and 'multiply by 60' in w, w
    q = float(w.split(' times the logged')[0].split()[-1])   # the figure: ~60
    assert 40 < q < 80, w
    with pytest.raises(TrialDataError, match='--strict.*looks like rev/s'):
        mt.load_trials(rps, ship=suzaku, strict=True)
    mt.load_trials(clean, ship=suzaku, strict=True)


def test_evaluate_says_rev_per_s_and_strict_refuses(logs, tmp_path, capsys):
    _, rps = logs
    code = run_command(evaluate_command, [str(rps), '--ship', 'suzaku', '--out',
                                          str(tmp_path / 'e'), '--no-plots', '--quiet'])
    out = capsys.readouterr()
    assert code == 0 and "channel 'rpm'" in out.err and 'looks like rev/s' in out.err, out
    code = run_command(evaluate_command, [str(rps), '--ship', 'suzaku', '--out',
                                          str(tmp_path / 's'), '--strict', '--quiet'])
    out = capsys.readouterr()
    assert code == 2 and 'ERROR: --strict' in out.err and 'rev/s' in out.err, out
    assert 'Traceback' not in out.err


# --------------------------------------------------------------- the one safe YAML reader
def test_plausibility_tolerances_are_read_by_the_safe_reader(tmp_path, monkeypatch):
    assert plausibility.load_yaml is _limits.load_yaml and not hasattr(plausibility, 'yaml')
    bomb = tmp_path / 'config' / plausibility.CONFIG_NAME
    bomb.parent.mkdir()
    bomb.write_text('a: &a [x, x, x, x, x, x, x, x, x, x]\n' + ''.join(
        f'{c}: &{c} [*{p}, *{p}, *{p}, *{p}, *{p}, *{p}, *{p}, *{p}, *{p}, *{p}]\n'
        for p, c in zip('abcdefgh', 'bcdefghi')))
    monkeypatch.setattr(plausibility, '_config_path', lambda: bomb)
    plausibility.tolerances.cache_clear()
    try:
        with pytest.raises(ConfigError, match=str(bomb)):
            plausibility.tolerances()
    finally:
        plausibility.tolerances.cache_clear()


# ------------------------------------------------------- the API refuses an impossible model
def _still(ship, T=30, dt=0.5):
    x0 = [0.0, 0.0, 0.0, 1.0, 0.0, 0.0]
    return Trial(np.arange(T) * dt, np.tile(x0, (T, 1)),
                 inputs={'rpm': np.full(T, 600.0), 'rudder': np.zeros(T)})


def test_api_simulate_and_evaluate_refuse_an_impossible_model_in_memory():
    ship = mt.load_ship('esso_osaka_3m_control').with_params({'m11': 0})
    for call in (lambda: mt.simulate(ship, _still(ship)),
                 lambda: mt.evaluate(ship, [_still(ship)])):
        with pytest.raises(ConfigError) as exc:
            call()
        msg = str(exc.value)
        assert '\n' not in msg and 'm11 = 0 must be positive' in msg, msg
        assert 'esso_osaka_3m_control, as given to' in msg, msg


def test_api_simulate_warns_once_on_an_implausible_model(suzaku, caplog):
    bad = suzaku.with_params({'N_r': 0.0571})   # the sign error of issue 45
    tr = _still(bad)
    with caplog.at_level(logging.WARNING):
        mt.simulate(bad, tr)
        mt.simulate(bad, tr)
    w = _warnings(caplog, 'N_r = 0.0571')
    assert len(w) == 1 and 'as given to simulate' in w[0], w


# ------------------------------------------------------------------ a network's full helm
def _net(dr_per_rudder=0.0, du=0.0, window=2, dt=1.0):
    """Return a one-layer network: dr = dr_per_rudder * rudder [rad], du a constant."""
    W = np.zeros((3, window * N_FEATURES))
    W[2, (window - 1) * N_FEATURES + FEATURES.index('rudder')] = dr_per_rudder
    return ResidualNet(window, dt, (W,), (np.array([du, 0.0, 0.0]),), np.zeros(N_FEATURES),
                       np.ones(N_FEATURES), np.ones(3), True)


def _params(tmp_path, net, name):
    d = tmp_path / name
    d.mkdir()
    net.save(d / 'params.residual.npz')
    (d / 'params.yaml').write_text(yaml.safe_dump(
        {'ship': 'suzaku', 'params': {'t_P': 0.2}, 'residual': 'params.residual.npz'}))
    return d / 'params.yaml'


def test_a_plain_network_is_plausible(suzaku):
    assert network_findings(suzaku, zero_net(3, 0.5)) == []
    assert network_findings(suzaku, None) == []


def test_a_network_that_turns_the_wrong_way_is_named_at_load_and_in_the_api(
        suzaku, tmp_path, caplog):
    with caplog.at_level(logging.WARNING):
        model = mt.load_model('suzaku', _params(tmp_path, _net(-0.1), 'wrong'))
    w, w_port = _warnings(caplog, 'turns the wrong way')   # each side, once
    assert 'hybrid model' in w and '+35 deg rudder' in w and 'heading change of -' in w, w
    assert '-35 deg rudder' in w_port and 'port helm must turn to port' in w_port, w_port
    assert 'suzaku with ' in w and 'params.yaml' in w, w
    caplog.clear()
    with caplog.at_level(logging.WARNING):   # the same model again: said once
        mt.simulate(model, _still(model.ship, 20, 1.0))
    assert not _warnings(caplog, 'wrong way')
    fresh = mt.Model(suzaku, _net(-0.1))      # a network built in memory: said at the API
    with caplog.at_level(logging.WARNING):
        mt.simulate(fresh, _still(suzaku, 20, 1.0))
    assert _warnings(caplog, 'turns the wrong way')


def test_a_network_that_speeds_up_is_named_with_its_speed(suzaku):
    (f,) = network_findings(suzaku, _net(du=0.2))
    assert f.what == 'network speed' and f.figure > 1.5 * plausibility.service_speed(suzaku)
    assert f'reaches {f.figure:.3g} m/s' in f.text and '1.5 x the start' in f.text, f.text


def test_the_node_shows_a_network_finding_on_its_diagnostics(suzaku):
    pytest.importorskip('diagnostic_msgs')
    from mmg_tuner.ros.health import plausibility_status, WARN
    found = plausibility.checked(suzaku) + network_checked(suzaku, _net(-0.1))
    st = plausibility_status('/sim_node', 'suzaku', found)
    assert st.level == WARN and 'network turn to starboard' in st.message, st.message
    assert any('turns the wrong way' in kv.value for kv in st.values)


def test_sim_node_serves_a_wrong_way_network_with_a_warn_on_diagnostics(tmp_path, monkeypatch):
    rclpy = pytest.importorskip('rclpy')
    from mmg_tuner.ros.health import WARN
    from mmg_tuner.ros.sim_node import SimNode
    params = _params(tmp_path, _net(-0.1), 'node')
    if rclpy.ok():
        pytest.skip('the default ROS context is in use')
    for k, v in (('ROS_DOMAIN_ID', '231'), ('ROS_LOG_DIR', str(tmp_path)),   # a graph the
                 ('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')):   # ROS tests do not use
        monkeypatch.setenv(k, v)
    rclpy.init(args=['--ros-args', '-p', f'params_file:={params}', '-p', 'dt:=0.5'])
    try:   # the node in this process, its /diagnostics caught as it would publish them
        node = SimNode()
        sent = []
        node.diag_pub = type('Pub', (), {'publish': lambda self, m: sent.append(m)})()
        node._report(node._steady_s())
        node.destroy_node()
    finally:
        rclpy.shutdown()
    (st,) = [s for s in sent[0].status if s.name.endswith('model plausibility')]
    assert st.level == WARN and 'network turn to starboard' in st.message, st.message
