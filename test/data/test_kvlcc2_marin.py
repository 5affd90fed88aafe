"""KVLCC2, standard MMG method, against the real MARIN free-running tests (SIMMAN 2008)."""
from mmg_tuner.data.marin import compare_with_marin
import pytest


@pytest.fixture(scope='module')
def rows(kvlcc2):
    return {r['manoeuvre']: r for r in compare_with_marin(kvlcc2, 'hold_speed')}


def rel(row, key):
    return row['simulated'][key] / row['measured'][key] - 1


def test_measured_indices_match_the_data_readme(rows):
    """
    The data's README lists indices computed from the files.

    Our reader and index code must reproduce them (sign of delta, earth-fixed u/v, time rebuilt).
    """
    stbd, port = rows['turn_starboard_35']['measured'], rows['turn_port_35']['measured']
    assert stbd['advance_L'] == pytest.approx(3.10, abs=0.015)
    assert stbd['tactical_diameter_L'] == pytest.approx(3.33, abs=0.015)
    assert port['advance_L'] == pytest.approx(3.02, abs=0.015)
    assert port['tactical_diameter_L'] == pytest.approx(3.07, abs=0.015)
    z = rows['zigzag_10_starboard_first']['measured']
    assert (z['overshoot_1_deg'], z['overshoot_2_deg']) == pytest.approx((8.1, 22.0), abs=0.1)
    z = rows['zigzag_20_port_first']['measured']
    assert (z['overshoot_1_deg'], z['overshoot_2_deg']) == pytest.approx((15.7, 12.7), abs=0.1)


def test_turning_circles_within_explained_bounds(rows):
    # An independent implementation of the standard method lands within about 5 % of MARIN's
    # tactical diameter; the starboard turn misses by more because the model has no propeller
    # side force (see the asymmetry test): bounded by the 15 % outer limit.
    port, stbd = rows['turn_port_35'], rows['turn_starboard_35']
    assert abs(rel(port, 'tactical_diameter_L')) < 0.05
    assert abs(rel(stbd, 'tactical_diameter_L')) < 0.15
    for r in (port, stbd):
        assert abs(rel(r, 'advance_L')) < 0.05


def test_asymmetry_is_real_model_error(rows):
    """
    The MARIN starboard circle is ~8 % larger; the standard model turns almost symmetrically.

    Not tuned away: the diagnosis must find it.
    """
    key = 'tactical_diameter_L'
    meas = rows['turn_starboard_35']['measured'][key] / rows['turn_port_35']['measured'][key]
    sim = rows['turn_starboard_35']['simulated'][key] / rows['turn_port_35']['simulated'][key]
    assert meas > 1.07
    assert abs(sim - 1) < 0.02


def test_zigzag_overshoots(rows):
    # 20/20: first and second overshoots within 3.5 deg of MARIN's.
    for key in ('zigzag_20_port_first', 'zigzag_20_starboard_first'):
        for k in ('overshoot_1_deg', 'overshoot_2_deg'):
            assert abs(rows[key]['simulated'][k] - rows[key]['measured'][k]) < 3.5
    # 10/10: the model under-predicts the overshoots (less yaw-unstable than the real hull);
    # the first overshoot within 4 deg, and on the low side.
    for key in ('zigzag_10_port_first', 'zigzag_10_starboard_first'):
        d = rows[key]['simulated']['overshoot_1_deg'] - rows[key]['measured']['overshoot_1_deg']
        assert -4.0 < d < 0.0
