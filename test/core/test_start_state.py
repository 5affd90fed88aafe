"""
The one initial-state rule, core.trial.fitted_first_state.

A quadratic over the first seconds; a shorter window when the ship is not quadratic there.
"""
from mmg_tuner.core.trial import fitted_first_state, Trial
import numpy as np
import pytest


def _plain_quadratic(trial: Trial, window_s: float) -> np.ndarray:
    k = int(np.searchsorted(trial.t, trial.t[0] + window_s, side='right'))
    t = trial.t[:k] - trial.t[0]
    A = np.column_stack([np.ones(k), t, t * t])
    return np.linalg.lstsq(A, trial.states[:k], rcond=None)[0][0]


def _steady(rate_hz: float, noise: np.ndarray) -> Trial:
    t = np.arange(0.0, 60.0, 1.0 / rate_hz)
    u, r = 3.0, 0.002
    psi = 0.3 + r * t
    states = np.column_stack([u * t * np.cos(psi), u * t * np.sin(psi), psi,
                              np.full_like(t, u), np.zeros_like(t), np.full_like(t, r)])
    return Trial(t, states + noise[:len(t)], np.zeros((len(t), 2)), name='steady')


SIGMA = np.array([0.5, 0.5, 0.0035, 0.02, 0.02, 0.0009])   # the generator's sensor noise


@pytest.mark.parametrize('rate_hz', [1.0, 5.0])
def test_a_steady_start_keeps_the_whole_window(rate_hz):
    """White noise, or noise smoothed by a filter (correlated): the 10 s quadratic stands."""
    rng = np.random.default_rng(1)
    white = rng.normal(size=(400, 6)) * SIGMA
    # a 5-sample moving average, scaled back to the same deviation: a filtered recording
    smooth = np.apply_along_axis(lambda c: np.convolve(c, np.ones(5) / 5, 'same'), 0,
                                 rng.normal(size=(400, 6))) * SIGMA * np.sqrt(5.0)
    for noise in (white, smooth):
        tr = _steady(rate_hz, noise)
        assert np.array_equal(fitted_first_state(tr, 10.0), _plain_quadratic(tr, 10.0))


def test_a_start_under_full_thrust_is_fitted_on_a_shorter_window():
    """
    A tug put to full differential thrust at the first sample: r 0 -> 0.3 rad/s in ~1 s.

    The 10 s quadratic started it turning at about 0.2 rad/s (the 1:20 tug twin's random_2:
    its heading then stayed 0.26 rad off and the trial's held-out J was 10^4 x the others').
    """
    rng = np.random.default_rng(2)
    t = np.arange(0.0, 60.0, 0.2)
    r = 0.3 * (1.0 - np.exp(-t / 0.4)) * np.exp(-t / 30.0)
    psi = np.concatenate([[0.0], np.cumsum(0.5 * (r[1:] + r[:-1]) * 0.2)])
    u = 0.9 * (1.0 - np.exp(-t / 3.0))
    states = np.column_stack([np.cumsum(u * np.cos(psi)) * 0.2, np.cumsum(u * np.sin(psi)) * 0.2,
                              psi, u, np.zeros_like(t), r])
    noise = rng.normal(size=states.shape) * np.array([0.015, 0.015, 0.005, 0.01, 0.01, 0.004])
    tr = Trial(t, states + noise, np.zeros((len(t), 2)), name='from rest')
    plain = _plain_quadratic(tr, 10.0)
    fitted = fitted_first_state(tr, 10.0)
    assert abs(plain[5]) > 0.1                     # the old rule: turning from the start
    assert abs(fitted[5]) < 0.05                   # the ship at rest, within the noise's reach
    assert abs(fitted[3]) < abs(plain[3]) + 0.02   # and no worse in speed
