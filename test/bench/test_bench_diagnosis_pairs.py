"""
bench/bench_diagnosis.py's cases the seventh to ninth sessions fixed (issue 26), plain diagnosis.

The benchmark's own cases (SUZAKU with its 12 targets moved, ten 400 s trials at 1 Hz with
sensor noise, five tuned and five held out; quick budget, no advice loop): a wind and a rudder
offset hidden together. Both fail without this session's two changes, as the benchmark found:
seed 0 named the wind alone (bent 17 deg to take the offset's share; the pair at its true
values made one held-out trial worse by less than that trial's noise floor, which vetoed it),
seed 2 the wind alone (the offset, significant beside the wind where it was named, screened at
a loss beside it and was never re-tuned). And a false cause: a yaw moment bias (seed 2) was
named as a 6.8 m/s wind, the bias and a propeller side force listed as explaining the trials
as well; fitted jointly with the wind from before the wind was named, the bias leaves the wind
at 0 m/s. The eighth session: a rival replaces the named effect only when the joint fit
leaves that one at nothing (a rudder offset beside a current had been replaced by a mimic).
The tenth session: a cause as good as a rival is not named but left undecided, "one of them".
"""
import math

from bench.bench_diagnosis import run_case
import pytest


@pytest.mark.parametrize('seed', [pytest.param(s, marks=pytest.mark.slow) for s in (0, 2)])
def test_a_wind_and_a_rudder_offset_are_both_named_on_the_benchmarks_cases(suzaku, seed):
    row = run_case(suzaku, 'rudder_offset+wind', seed, 'quick', 10, 400.0, advice=False)
    assert sorted(row['named']) == ['rudder_offset', 'wind'], row['named']
    truth, est = row['truth'], row['estimates']
    assert est['wind_speed'] == pytest.approx(truth['wind_speed'], abs=1.0)
    dir_err = (math.degrees(est['wind_dir'] - truth['wind_dir']) + 180) % 360 - 180
    assert abs(dir_err) < 10
    assert math.degrees(est['rudder_offset']) == pytest.approx(
        math.degrees(truth['rudder_offset']), abs=0.5)


@pytest.mark.slow
def test_a_yaw_moment_bias_is_fitted_not_the_wind_it_was_first_named_as(suzaku):
    """The bias is fitted, as one of a set with the wind (as good alone): nothing named."""
    row = run_case(suzaku, 'yaw_moment_bias', 2, 'quick', 10, 400.0, advice=False)
    assert row['named'] == [], row['named']
    assert list(row['undecided']) == ['yaw_moment_bias'], row['undecided']
    assert 'wind' in row['undecided']['yaw_moment_bias']   # said: as good alone
    truth, est = row['truth']['yaw_moment_bias'], row['estimates']['yaw_moment_bias']
    assert est == pytest.approx(truth, rel=0.4)   # -1.69e-3 for -1.37e-3


@pytest.mark.slow
def test_a_rudder_offset_is_not_replaced_by_a_mimic_that_shares_its_error(suzaku):
    """
    Current 0.58 m/s and rudder offset -1.53 deg (seed 2 of the eighth session's class).

    The offset is named after the current, a wind, a yaw moment bias and a propeller side
    force listed as explaining the trials as well. Fitted jointly with the bias, the offset
    keeps -0.68 deg of its -1.35 deg alone: under the 1 deg worth finding, so the seventh
    session's swap named the bias in its place (with the side force: that one), a false cause.
    A rival now replaces the named effect only when the joint fit leaves it at nothing (under
    half the smallest worth finding), as a wind named for a yaw moment bias is left at 0 m/s.
    """
    row = run_case(suzaku, 'current+rudder_offset', 2, 'quick', 10, 400.0, advice=False)
    _assert_current_and_offset_found(row, undecided=True)
    # the offset is fitted, but these trials cannot tell it from its mimics: one of a set
    assert {'yaw_moment_bias', 'wind'} <= set(row['undecided']['rudder_offset'])


@pytest.mark.slow
def test_a_rudder_offset_the_base_mimics_is_found_beside_the_current_not_a_wind(suzaku):
    """
    Current 0.33 m/s and rudder offset -1.30 deg (seed 1 of the eighth session's class).

    The base coefficients mimic the offset (barely identifiable: a_H, epsilon and x_H take
    all of its signature), so beside the named current, with the base held, it screens at
    -2 % and was never fitted jointly: current + wind was named, a false cause, though
    current + offset with the base free leaves the smaller held-out error. The ninth session:
    while what remains is not noise, the barely identifiable effects are joint partners too.
    """
    row = run_case(suzaku, 'current+rudder_offset', 1, 'quick', 10, 400.0, advice=False)
    _assert_current_and_offset_found(row)
    assert row['remaining_is_noise'] is True


def _assert_current_and_offset_found(row: dict, undecided: bool = False) -> None:
    """
    Both found, the offset within 0.5 deg and the current within 0.1 m/s of the truth.

    ``undecided``: the offset is fitted but as good as a rival, so only the current is named.
    """
    if undecided:
        assert row['named'] == ['current'] and list(row['undecided']) == ['rudder_offset'], row
    else:
        assert sorted(row['named']) == ['current', 'rudder_offset'], row['named']
    truth, est = row['truth'], row['estimates']
    assert math.degrees(est['rudder_offset']) == pytest.approx(
        math.degrees(truth['rudder_offset']), abs=0.5)
    assert est['current_speed'] == pytest.approx(truth['current_speed'], abs=0.1)
