"""Plots a ROS user reads without a manual: inputs beside the states, signs and frames on axes."""
import matplotlib
from mmg_tuner.core.maneuvers import ManeuverSpec, run
from mmg_tuner.core.trial import Trial
import mmg_tuner.diagnosis.report as diag_report
from mmg_tuner.tuning import plots
import mmg_tuner.tuning.evaluate as evaluate_mod
from mmg_tuner.tuning.report import plot_trials
import numpy as np
import pytest

matplotlib.use('Agg')  # the test is the caller: library code never sets a backend

PNG = b'\x89PNG'


def _labels(fig) -> list[str]:
    return [a.get_ylabel() for a in fig.axes] + [a.get_xlabel() for a in fig.axes]


def _synthetic(thrusters=False, wind=False, T=50) -> Trial:
    t = np.arange(T, dtype=float)
    states = np.zeros((T, 6))
    states[:, 0] = 3.0 * t
    states[:, 3] = 3.0
    controls = np.column_stack([np.full(T, 100.0), np.radians(10.0) * np.sign(np.sin(t / 8))])
    return Trial(t, states, controls, name='zz',
                 thrusters=np.ones((T, 2)) if thrusters else None,
                 wind=np.full((T, 2), 2.0) if wind else None)


def test_figure_has_inputs_beside_states_and_axes_with_units_signs_frames():
    tr = _synthetic()
    fig = plots.trial_figure(tr, {'tuned': tr.states + 0.1}, 'zz')
    labels = ' '.join(_labels(fig))
    for needed in ('rudder', '+ to starboard', 'rpm', 'x_E [m, north]', 'y_E [m, east]',
                   'clockwise', 'from north', 't [s]'):
        assert needed in labels, needed
    assert 'thrusters' not in labels and 'wind' not in labels
    assert all(a.get_ylabel() for a in fig.axes)   # no unlabelled panel
    legend = [t.get_text() for lg in fig.legends for t in lg.get_texts()]
    assert legend == ['measured', 'simulated: tuned']
    # the rudder panel shows the rudder in degrees
    rud = next(a for a in fig.axes if a.get_ylabel().startswith('rudder'))
    assert np.nanmax(rud.lines[0].get_ydata()) == pytest.approx(10.0)
    assert plots.png_bytes(fig).startswith(PNG)


def test_thrusters_and_measured_wind_get_their_own_panels():
    tr = _synthetic(thrusters=True, wind=True)
    labels = ' '.join(_labels(plots.trial_figure(tr, {}, '')))
    assert 'thrusters [rev/s' in labels and 'wind' in labels


def test_restarts_break_the_simulated_line():
    tr = _synthetic()
    fig = plots.trial_figure(tr, {'model': tr.states}, '', restarts_s=tr.t[20::20])
    psi = next(a for a in fig.axes if a.get_ylabel().startswith('psi'))
    # measured + 3 segments of the model + 2 restart lines
    assert len(psi.lines) == 1 + 3 + 2


def test_title_names_the_set_and_the_error():
    title = plots.trial_title('zz', 'test', {'pre': 2.0, 'tuned': float('inf')})
    assert 'held-out' in title and '2' in title and 'inf (diverged)' in title
    assert 'tuning trial' in plots.trial_title('zz', 'tune', {'tuned': 1.0})


@pytest.fixture(scope='module')
def zigzag(suzaku):
    return run(suzaku, ManeuverSpec('zigzag', 20.0, duration_s=120.0, dt=1.0))


def test_tuning_plots_mark_tuning_and_held_out_with_J(suzaku, zigzag, monkeypatch):
    figs = []
    make = plots.trial_figure
    monkeypatch.setattr(plots, 'trial_figure', lambda *a, **k: figs.append(make(*a, **k))
                        or figs[-1])
    other = Trial(zigzag.t, zigzag.states, zigzag.controls, name='other')
    images = plot_trials(suzaku, [zigzag, other], {'tuned': suzaku.params}, 'plot_',
                         sets={zigzag.name: 'tune', 'other': 'test'},
                         J={'tuned': {zigzag.name: 0.5, 'other': 1.5}})
    assert sorted(images) == sorted([f'plot_{zigzag.name}.png', 'plot_other.png'])
    assert all(b.startswith(PNG) for b in images.values())
    titles = [f.get_suptitle() for f in figs]
    assert 'tuning trial' in titles[0] and '0.5' in titles[0]
    assert 'held-out' in titles[1] and '1.5' in titles[1]
    assert any(a.get_ylabel().startswith('rudder') for a in figs[0].axes)


def test_evaluate_plot_has_inputs_index_and_restarts(suzaku, zigzag, monkeypatch):
    figs = []
    make = evaluate_mod.trial_figure
    monkeypatch.setattr(evaluate_mod, 'trial_figure',
                        lambda *a, **k: figs.append(make(*a, **k)) or figs[-1])
    res = evaluate_mod.evaluate(suzaku, [zigzag], restart_every_s=50.0)
    images = res.plots()
    assert list(images) == [f'evaluate_{zigzag.name}.png']
    labels = ' '.join(_labels(figs[0]))
    assert 'rudder' in labels and 'rpm' in labels and 'x_E' in labels
    assert 'index' in figs[0].get_suptitle() and '50 s' in figs[0].get_suptitle()


def test_residual_plot_has_the_rudder_and_signed_errors(zigzag, monkeypatch):
    figs = []
    monkeypatch.setattr(diag_report, 'png_bytes', lambda f: figs.append(f) or PNG)
    sim = zigzag.states + 0.01
    images = diag_report.plot_residuals([zigzag], [sim], [zigzag.states])
    assert set(images) == {'residuals_time.png', 'residuals_vs_heading.png'}
    labels = ' '.join(_labels(figs[0]))
    assert 'rudder' in labels and '+ sim. more clockwise' in labels
    assert 'clockwise from north' in ' '.join(_labels(figs[1]))
