"""Ship configs are data: loading, overlays and errors that name the file and key."""
from mmg_tuner.core.ship import load_params_file, load_ship, resolve_config_path
from mmg_tuner.errors import ConfigError
import numpy as np
import pytest
import yaml


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
    with pytest.raises(ConfigError, match='unknown ship') as err:
        load_ship('titanic')
    # the list offers ships only, not the node, topic or demo configs beside them
    assert 'suzaku' in str(err.value) and 'sim_node' not in str(err.value)
    assert 'topics' not in str(err.value) and 'demo_truth' not in str(err.value)


# --- issue 10: every bad ship file or overlay gives a ConfigError naming file, key and value

def _suzaku_doc():
    return yaml.safe_load(resolve_config_path('suzaku').read_text())


@pytest.mark.parametrize('section,key,value,words', [
    ('particulars', 'L_pp', 'long', "L_pp = 'long'"),
    ('particulars', 'B', None, 'B = None'),
    ('hull', 'R_0', [1, 2], 'R_0 = [1, 2]'),
    ('particulars', 'rho', True, 'rho = True'),
    ('particulars', 'm', -100.0, 'm = -100'),
    ('particulars', 'L_pp', 0.0, 'L_pp = 0'),
    ('particulars', 'D_P', -1.0, 'D_P = -1'),
    ('particulars', 'A_R', 0.0, 'A_R = 0'),
    ('particulars', 'rho', -1025.0, 'rho = -1025'),
    ('added_mass', 'm_x', -0.02, 'm_x = -0.02'),
    ('hull', 'R_0', 1e300, 'R_0 = 1e+300'),
    ('hull', 'Y_v', '.nan', 'Y_v'),
])
def test_bad_ship_values_are_named(tmp_path, section, key, value, words):
    doc = _suzaku_doc()
    doc[section][key] = value
    f = tmp_path / 'bad.yaml'
    f.write_text(yaml.safe_dump(doc))
    with pytest.raises(ConfigError) as e:
        load_ship(f)
    assert str(f) in str(e.value) and words in str(e.value)


@pytest.mark.parametrize('content', [b'\x00\x01\x02\xff\xfe binary', b'caf\xe9: 1\n',
                                     b'- 1\n- 2\n', b'just a string', b'model: [container]\n',
                                     b'model: container\nhull: [1, 2]\n',
                                     b'model: container\nsteering: {rate_deg_s: fast}\n'])
def test_unreadable_or_non_mapping_ship_files(tmp_path, content):
    f = tmp_path / 'bad.yaml'
    f.write_bytes(content)
    with pytest.raises(ConfigError, match='bad.yaml'):
        load_ship(f)


@pytest.mark.parametrize('overlay,words', [({'m': -100}, 'm = -100'), ({'L_pp': 0}, 'L_pp = 0'),
                                           ({'R_0': 1e300}, 'R_0'), ({'t_P': 'x'}, 't_P'),
                                           ({'m_y': -1.0}, 'm_y = -1')])
def test_params_overlay_is_validated_like_a_ship_file(tmp_path, overlay, words):
    f = tmp_path / 'params.yaml'
    f.write_text(yaml.safe_dump({'params': overlay}))
    with pytest.raises(ConfigError) as e:
        load_ship('suzaku', f)
    assert str(f) in str(e.value) and words in str(e.value)


def test_fuzzed_ship_values_and_overlays_give_config_errors(tmp_path):
    """
    Hypothesis over hostile values anywhere in the ship file and in an overlay.

    Loading either succeeds or raises ConfigError, never another exception.
    """
    from hypothesis import HealthCheck, given, settings
    from hypothesis import strategies as st
    doc = _suzaku_doc()
    keys = [(sec, k) for sec in ('particulars', 'added_mass', 'hull', 'propeller', 'rudder',
                                 'steering', 'tuning') for k in (doc.get(sec) or {})]
    values = st.one_of(st.none(), st.booleans(), st.text(max_size=5),
                       st.floats(allow_nan=True, allow_infinity=True), st.integers(),
                       st.lists(st.integers(), max_size=2), st.dictionaries(st.text(max_size=2),
                                                                            st.integers(),
                                                                            max_size=1))
    f = tmp_path / 'fuzz.yaml'
    g = tmp_path / 'params.yaml'

    @settings(max_examples=150, deadline=None, suppress_health_check=list(HealthCheck))
    @given(st.sampled_from(keys), values, st.sampled_from(['m', 'L_pp', 'R_0', 't_P', 'x_G']),
           values)
    def check(where, value, okey, ovalue):
        bad = yaml.safe_load(yaml.safe_dump(doc))
        bad[where[0]][where[1]] = value
        f.write_text(yaml.safe_dump(bad))
        g.write_text(yaml.safe_dump({'params': {okey: ovalue}}))
        for args in ((f,), ('suzaku', g)):
            try:
                load_ship(*args)
            except ConfigError:
                pass

    check()
