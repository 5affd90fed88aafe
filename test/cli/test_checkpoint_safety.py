"""
Checkpoints are data, never code (issue 28 item 1).

A folder handed over by someone else may hold a ``checkpoint.pkl`` whose pickle runs a command
when loaded. ``tune --resume`` and ``diagnose --resume`` (and the API) must refuse it without
loading it; the checkpoints they write are JSON and ``.npz`` read with ``allow_pickle=False``,
validated (format, version, ship, shapes) before use.
"""
import json
import os
import pickle

import mmg_tuner as mt
from mmg_tuner.cli import diagnose as cli_diagnose
from mmg_tuner.cli import tune as cli_tune
from mmg_tuner.data.generate import generate_trial, SensorNoise
from mmg_tuner.diagnosis.checkpoint import SearchCheckpoint
from mmg_tuner.tuning import Objective, ParameterSpace, TrialBatch, Tuner
from mmg_tuner.tuning import tuner as tuner_mod
import numpy as np
import pytest


class _Evil:
    """Unpickling this runs ``touch MARKER``: what a handed-over checkpoint.pkl could do."""

    def __init__(self, marker):
        self.marker = str(marker)

    def __reduce__(self):
        return (os.system, (f'touch {self.marker}',))


def _evil_pickle(path, marker) -> None:
    path.write_bytes(pickle.dumps({'version': 1, 'payload': _Evil(marker)}))


@pytest.fixture(scope='module')
def trials(suzaku):
    specs = [('turning', 35), ('zigzag', 20), ('turning', -25), ('zigzag', -15)]
    return [generate_trial(suzaku, m, a, None, 106.0, 3.086, 60.0, 1.0, SensorNoise(), 5 + i,
                           f'{m}{a:+d}')[1] for i, (m, a) in enumerate(specs)]


@pytest.fixture(scope='module')
def csv_files(trials, tmp_path_factory):
    from mmg_tuner.data.csv_io import write_trial_csv
    d = tmp_path_factory.mktemp('csv')
    out = []
    for t in trials:
        write_trial_csv(t, d / f'{t.name}.csv')
        out.append(str(d / f'{t.name}.csv'))
    return out


def _handed_over_folder(tmp_path, command, options, marker):
    """Make an output folder as a stranger could hand it over: args.json, a malicious pickle."""
    out = tmp_path / 'handed_over'
    out.mkdir()
    (out / 'args.json').write_text(json.dumps({'command': command, 'version': 2,
                                               'options': {**options, 'out': str(out)}}))
    _evil_pickle(out / 'checkpoint.pkl', marker)
    return out


@pytest.mark.parametrize('command', ['tune', 'diagnose'])
def test_resume_never_unpickles_a_handed_over_checkpoint(command, csv_files, tmp_path, capsys):
    marker = tmp_path / 'PWNED'
    opts = {'trials': csv_files[:2], 'quiet': True, 'no_plots': True}
    if command == 'tune':
        main, opts = cli_tune.main, {**opts, 'max_evals': 50}
    else:
        main, opts = cli_diagnose.main, {**opts, 'test': csv_files[2:], 'budget': 'quick'}
    out = _handed_over_folder(tmp_path, command, opts, marker)
    with pytest.raises(SystemExit) as stop:
        main(['--resume', str(out)])
    assert not marker.exists(), 'the checkpoint was unpickled: its code ran'
    assert stop.value.code == 2
    err = capsys.readouterr().err
    assert 'Traceback' not in err
    line = [ln for ln in err.splitlines() if ln.startswith('ERROR:')]
    assert len(line) == 1, err
    assert 'checkpoint.pkl' in line[0] and 'without --resume' in line[0]
    assert (out / 'checkpoint.pkl').is_file()   # refused, neither loaded nor removed


def test_api_resume_refuses_a_pickle_whatever_its_name(suzaku, trials, tmp_path):
    marker = tmp_path / 'PWNED'
    space = ParameterSpace.around(suzaku, ['R_0', 't_P'])
    obj = Objective(suzaku, TrialBatch.from_trials(trials[:1]))
    for name in ('checkpoint.pkl', 'checkpoint.npz'):   # content decides, not the name
        ck = tmp_path / name
        _evil_pickle(ck, marker)
        with pytest.raises(mt.TuningError, match=f'{name}.*without --resume'):
            Tuner(space, obj, seed=1, checkpoint=ck).run(resume=True)
        with pytest.raises(mt.DiagnosisError, match=f'{name}.*without --resume'):
            SearchCheckpoint(ck, 'fp', resume=True)
    assert not marker.exists()


def test_checkpoint_is_plain_data_and_round_trips_the_optimizer_exactly(suzaku, trials, tmp_path):
    space = ParameterSpace.around(suzaku, ['R_0', 't_P', 'gamma_Rn'])
    obj = Objective(suzaku, TrialBatch.from_trials(trials[:1]))
    ck = tmp_path / 'ck.npz'
    stop = {'n': 0}

    def interrupt(p):
        stop['n'] += 1
        if stop['n'] == 3:
            raise KeyboardInterrupt

    Tuner(space, obj, seed=2, max_evaluations=300, checkpoint=ck).run(progress=interrupt)
    with np.load(ck, allow_pickle=False) as z:   # loads with pickling disabled
        files = set(z.files)
        assert all(z[k].dtype.kind in 'biufU' for k in z.files)
    assert 'meta' in files and 'cma._C' in files
    t = Tuner(space, obj, seed=2, max_evaluations=300, checkpoint=ck)
    state = t._load()
    again = t._decode(t._encode(state), ck)
    for k, v in vars(state.optimizer).items():
        if k == '_rng':
            continue
        w = vars(again.optimizer)[k]
        assert type(w) is type(v), k
        np.testing.assert_array_equal(w, v, err_msg=k)   # to the last digit
    rng_a, rng_b = state.optimizer._rng.get_state(), again.optimizer._rng.get_state()
    assert all(np.array_equal(a, b) for a, b in zip(rng_a, rng_b))


def test_a_damaged_or_foreign_checkpoint_is_refused_naming_the_file(suzaku, kvlcc2, trials,
                                                                    tmp_path):
    space = ParameterSpace.around(suzaku, ['R_0', 't_P'])
    obj = Objective(suzaku, TrialBatch.from_trials(trials[:1]))
    ck = tmp_path / 'ck.npz'
    Tuner(space, obj, seed=1, max_evaluations=40, checkpoint=ck).run()
    with np.load(ck, allow_pickle=False) as z:
        arrays = {k: z[k] for k in z.files}
    bad = tmp_path / 'shape.npz'
    np.savez(bad, **{**arrays, 'cma._mean': np.zeros(5)})
    with pytest.raises(mt.TuningError, match=r'shape\.npz.*_mean.*shape'):
        Tuner(space, obj, seed=1, max_evaluations=40, checkpoint=bad).run(resume=True)
    meta = json.loads(str(arrays['meta']))
    other = tmp_path / 'ship.npz'
    np.savez(other, **{**arrays, 'meta': np.array(json.dumps({**meta, 'ship': 'kvlcc2'}))})
    with pytest.raises(mt.TuningError, match=r'ship\.npz.*kvlcc2.*suzaku'):
        Tuner(space, obj, seed=1, max_evaluations=40, checkpoint=other).run(resume=True)
    newer = tmp_path / 'version.npz'
    np.savez(newer, **{**arrays, 'meta': np.array(json.dumps({**meta, 'version': 99}))})
    with pytest.raises(mt.TuningError, match=r'version\.npz.*version 99'):
        Tuner(space, obj, seed=1, max_evaluations=40, checkpoint=newer).run(resume=True)
    cut = tmp_path / 'cut.npz'
    cut.write_bytes(ck.read_bytes()[:200])
    with pytest.raises(mt.TuningError, match=r'cut\.npz'):
        Tuner(space, obj, seed=1, max_evaluations=40, checkpoint=cut).run(resume=True)
    # the diagnosis store: JSON, validated the same way
    store = SearchCheckpoint(tmp_path / 'dx.json', 'fp-1')
    store.put(SearchCheckpoint.key('a'), np.array([0.1, 1 / 3]))
    doc = json.loads((tmp_path / 'dx.json').read_text())
    again = SearchCheckpoint(tmp_path / 'dx.json', 'fp-1', resume=True)
    assert again.get(SearchCheckpoint.key('a')).tolist() == [0.1, 1 / 3]   # exact
    doc['done'][SearchCheckpoint.key('a')] = ['x']
    (tmp_path / 'dx.json').write_text(json.dumps(doc))
    with pytest.raises(mt.DiagnosisError, match=r'dx\.json'):
        SearchCheckpoint(tmp_path / 'dx.json', 'fp-1', resume=True)
    assert tuner_mod.CHECKPOINT_VERSION >= 2
