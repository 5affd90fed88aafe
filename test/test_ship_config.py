"""Ship configs are data: loading, overlays and errors that name the file and key."""
import numpy as np
import pytest
import yaml

from mmg_tuner.core.ship import load_params_file, load_ship, resolve_config_path
from mmg_tuner.errors import ConfigError


def test_suzaku_values_as_in_the_paper(suzaku):
    assert suzaku.model == 'container'
    assert suzaku['X_vr'] == pytest.approx(0.160 - 0.168)   # Table 4 lists X'_vr + m'_y
    assert suzaku['Y_r'] == pytest.approx(0.090 + 0.010)    # Table 4 lists Y'_r - m'_x
    assert suzaku['m'] == pytest.approx(1025 * 0.737 * 83.0 * 13.5 * 3.8)
    assert suzaku['I_zG'] == pytest.approx(suzaku['m'] * (0.25 * 83.0) ** 2)
    assert suzaku.tuning_targets == ('R_0', 't_P', 'w_P0', 'C_w', 't_R', 'a_H', 'x_H',
                                     'epsilon', 'kappa', 'l_R', 'gamma_Rp', 'gamma_Rn')


def test_kvlcc2_is_standard_model(kvlcc2):
    assert kvlcc2.model == 'standard' and kvlcc2.scale_ratio == pytest.approx(45.714)
    assert kvlcc2['m'] == pytest.approx(1025 * 3.27)
    assert kvlcc2.rudder_rate_rad_s == pytest.approx(np.radians(15.68))


def test_params_overlay(tmp_path, suzaku):
    f = tmp_path / 'params.yaml'
    f.write_text(yaml.safe_dump({'ship': 'suzaku', 'params': {'t_P': 0.1, 'a_H': 0.2}}))
    ship = load_ship('suzaku', f)
    assert ship['t_P'] == 0.1 and ship['a_H'] == 0.2 and ship['R_0'] == suzaku['R_0']
    f.write_text(yaml.safe_dump({'params': {'not_a_param': 1.0}}))
    with pytest.raises(ConfigError, match='unknown parameter'):
        load_params_file(f)


def test_config_errors_name_file_and_key(tmp_path):
    doc = yaml.safe_load(resolve_config_path('suzaku').read_text())
    doc['hull']['X_vvx'] = 1.0
    f = tmp_path / 'bad.yaml'
    f.write_text(yaml.safe_dump(doc))
    with pytest.raises(ConfigError, match=r'bad.yaml: hull.X_vvx is not a known parameter'):
        load_ship(f)
    del doc['hull']['X_vvx']
    doc['particulars']['B'] = -1
    f.write_text(yaml.safe_dump(doc))
    with pytest.raises(ConfigError, match='B must be positive'):
        load_ship(f)
    with pytest.raises(ConfigError, match='unknown ship'):
        load_ship('titanic')
