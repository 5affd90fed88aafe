"""
No model that cannot be a ship runs in silence (issue 45; issue 43 item 3).

core/plausibility.py: impossible models refused at load with one line, implausible ones named
with the figure; the published ships pass; the gate before params.yaml is written
(tuning/gate.py); the simulator node's diagnostics status (ros/health.py).
"""
from mmg_tuner.core import plausibility as pl
from mmg_tuner.core.ship import embedded_ship_files, load_ship
from mmg_tuner.errors import ConfigError, TuningError
from mmg_tuner.tuning.gate import check_before_writing
import pytest
import yaml

TUG_PROBE = {'m22': 87.2, 'm23': -12.7, 'm32': -24.6, 'm33': 2.32}   # issue 43's LO result


def _params(tmp_path, ship, values, name='params.yaml'):
    path = tmp_path / name
    path.write_text(yaml.safe_dump({'ship': ship, 'params': values}))
    return path


def _what(ship):
    return {f.what: f for f in pl.check_model(ship)}


def test_published_ships_pass():
    names = {f.stem for f in embedded_ship_files()}
    assert {'suzaku', 'kvlcc2', 'esso_osaka_3m', 'esso_osaka_3m_control', 'qiuxin_tug',
            'qiuxin_tug_simplified6', 'otter_usv'} <= names
    for name in sorted(names):
        found = pl.check_model(load_ship(name))
        assert not [f for f in found if f.level == 'error'], (name, found)
        if name == 'esso_osaka_3m_control':   # its starting values: no rudder fin damping
            assert [f.what for f in found] == ['straight-line stability'], found
            assert found[0].figure > 1.0
        else:
            assert found == [], (name, found)
    demo = load_ship('suzaku', 'config/demo_truth.yaml')
    assert pl.check_model(demo) == []


def test_kvlcc2_mildly_unstable_within_the_tolerance():
    ship = load_ship('kvlcc2')
    U, act = pl._straight_run(ship)
    growth = max(pl.sway_yaw_eigenvalues(ship, U, act).real) * ship.L_pp / U
    tol = pl.tolerances()['stability']['max_growth_per_length']
    assert 0 < growth < tol   # course-unstable, as published, and not warned about


def test_suzaku_with_wrong_signs_warns_with_the_figure():
    ship = load_ship('suzaku')
    found = _what(ship.with_params({'N_r': 0.057}))
    assert set(found) == {'N_r sign', 'straight-line stability'}
    assert all(f.level == 'warning' for f in found.values())
    assert found['straight-line stability'].figure > 1.0
    assert 'per ship length' in found['straight-line stability'].text
    found = _what(ship.with_params({'N_r': 0.057, 'Y_v': 0.3}))
    assert {'N_r sign', 'Y_v sign', 'straight-line stability'} <= set(found)
    assert 'Y_v = 0.3' in found['Y_v sign'].text


def test_wrong_way_turn_warns():
    # the rudder at the bow (x'_R = +0.5): starboard helm turns the ship to port
    found = _what(load_ship('suzaku').with_params({'x_R': 0.5}))
    assert 'turn direction' in found
    assert 'wrong way' in found['turn direction'].text


@pytest.mark.parametrize('ship, values, words', [
    ('qiuxin_tug', {'m11': 0}, 'm11 = 0 must be positive'),
    ('qiuxin_tug', TUG_PROBE, 'determinant -110.1 <= 0'),
    ('qiuxin_tug', {'X_absu_u': 250.0}, 'pushes the ship ahead'),
    ('suzaku', {'R_0': -0.01}, 'R_0 = -0.01 must not be negative'),
    ('qiuxin_tug_simplified6', {'m33': -1.0}, 'm33 = -1 must be positive'),
])
def test_impossible_overlay_refused_in_one_line(tmp_path, ship, values, words):
    path = _params(tmp_path, ship, values)
    with pytest.raises(ConfigError) as exc:
        load_ship(ship, path)
    msg = str(exc.value)
    assert words in msg and str(path) in msg and '\n' not in msg
    assert pl.impossible(load_ship(ship).with_params(values))[0].level == 'error'


def test_simulate_command_refuses_m11_zero_without_traceback(tmp_path, capsys):
    from mmg_tuner.cli.simulate import main
    path = _params(tmp_path, 'qiuxin_tug', {'m11': 0})
    with pytest.raises(SystemExit) as exc:
        main(['--ship', 'qiuxin_tug', '--params', str(path), '--out', str(tmp_path / 'a.csv')])
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert err.startswith('ERROR: ') and 'm11 = 0 must be positive' in err
    assert 'Traceback' not in err and len(err.strip().splitlines()) == 1
    assert not (tmp_path / 'a.csv').exists()


def test_warning_printed_once_by_the_loaders(tmp_path, caplog):
    from mmg_tuner._ship_params import load_ship_with_params
    path = _params(tmp_path, 'suzaku', {'N_r': 0.058}, 'nr.yaml')
    with caplog.at_level('WARNING', logger='mmg_tuner'):
        load_ship_with_params('suzaku', path)
        load_ship_with_params('suzaku', path)   # tune loads twice: printed once
    lines = [r.getMessage() for r in caplog.records if 'plausibility' in r.name]
    assert len(lines) == 2 and all(ln.startswith('WARNING: suzaku with ') for ln in lines)
    assert any('straight-line unstable' in ln for ln in lines)


def test_gate_before_writing():
    tug = load_ship('qiuxin_tug')
    with pytest.raises(TuningError) as exc:
        check_before_writing(tug, TUG_PROBE, [], 'identified parameters')
    assert 'determinant' in str(exc.value) and '--write-unphysical' in str(exc.value)
    marks = check_before_writing(tug, TUG_PROBE, [], 'identified parameters',
                                 write_unphysical=True)
    assert marks and marks[0].startswith('UNPHYSICAL, written with --write-unphysical')
    assert check_before_writing(tug, {'m11': 140.0}, []) == []
    marks = check_before_writing(load_ship('suzaku'), {'N_r': 0.057}, [])
    assert marks and all(m.startswith('implausible: ') for m in marks)


def test_node_diagnostics_warn_for_an_implausible_ship():
    pytest.importorskip('diagnostic_msgs')
    from diagnostic_msgs.msg import DiagnosticStatus
    from mmg_tuner.ros.health import plausibility_status
    bad = pl.checked(load_ship('suzaku').with_params({'N_r': 0.057}))
    s = plausibility_status('/sim_node', 'suzaku', bad)
    assert s.level == DiagnosticStatus.WARN and s.name == '/sim_node: model plausibility'
    assert 'straight-line stability' in s.message
    kv = {v.key: v.value for v in s.values}
    assert 'per ship length' in kv['straight-line stability']
    ok = plausibility_status('/sim_node', 'suzaku', pl.checked(load_ship('suzaku')))
    assert ok.level == DiagnosticStatus.OK and ok.message == 'plausible'
