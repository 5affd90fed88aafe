"""
FRT-DS-ESSO pond data (data/esso_osaka_frt).

The reader, its conventions checked against the data, robustness on damaged copies, and cutting at
events.
"""
import math
import shutil

from mmg_tuner.core.models.lowspeed import apparent_wind_ne
from mmg_tuner.data import esso
from mmg_tuner.data.load import load_trials
from mmg_tuner.errors import MmgTunerError, TrialDataError
import numpy as np
import pytest

DATA = esso.esso_data_dir()
TURN = DATA / 'turning' / 'turn_14-Sep-2020_13_39_32.csv'      # n 10, +35 deg helm
ZIGZAG_NAN = DATA / 'zigzag' / 'zigzag_31-Jul-2020_13_50_28.csv'
BERTHING = DATA / 'berthing' / 'berthing_12-Nov-2020_11_14_47.csv'


def test_data_shipped_with_licence_and_note():
    files = sorted(DATA.rglob('*.csv'))
    assert len(files) == 33
    assert 'Attribution-NonCommercial-ShareAlike 4.0' in (DATA / 'LICENSE').read_text()
    readme = (DATA / 'README.md').read_text()
    assert readme.startswith('> Copied into this repository') and 'FRT-DS-ESSO' in readme


def test_every_file_reads_both_ways():
    kept = esso.read_esso(DATA, keep_astern=True)
    assert len(kept) == 33                     # one whole trial per run
    default = esso.read_esso(DATA)
    assert len(default) > 33                   # split around astern / u <= 0
    total_kept = sum(t.duration_s for t in kept)
    total_default = sum(t.duration_s for t in default)
    assert total_default < 0.85 * total_kept
    for tr in default:
        assert np.all(tr['rpm'] > 0) and np.all(tr['u'] > 0)
    for tr in kept:
        assert tr.wind is not None and np.all(np.isfinite(tr.wind))
        assert np.all(np.isfinite(tr.states)) and np.all(np.isfinite(tr.controls))
        assert tr.dt == pytest.approx(0.1)


def test_astern_kept_only_when_asked():
    kept = esso.read_esso_csv(BERTHING, keep_astern=True)
    assert len(kept) == 1 and kept[0]['rpm'].min() < 0 and kept[0]['u'].min() < 0
    assert any('kept' in n for n in kept[0].notes)
    default = esso.read_esso_csv(BERTHING)
    notes = default[0].notes
    assert any('rpm <= 0' in n and 'left out' in n for n in notes)
    # load_trials dispatches on the column names and passes keep_astern through
    via_load = load_trials(BERTHING, keep_astern=True)
    np.testing.assert_array_equal(via_load[0].states, kept[0].states)
    assert len(load_trials(BERTHING)) == len(default)


def test_units_and_frame_against_the_raw_file():
    cols, _ = esso.read_esso_table(TURN)
    tr = esso.read_esso_csv(TURN, keep_astern=True)[0]
    np.testing.assert_allclose(tr['rpm'], 60.0 * cols['n_prop [rps]'])
    np.testing.assert_allclose(tr['x'], cols['x_position_mid [m]'])
    np.testing.assert_allclose(tr['v'], cols['vm_velo [m/s]'])
    np.testing.assert_allclose(np.angle(np.exp(1j * (tr['psi'] - cols['psi_hat [rad]']))), 0,
                               atol=1e-12)    # unwrapped only
    # pond frame = MMG earth frame, heading clockwise: x' = u cos psi - v sin psi fits better
    # than the counter-clockwise reading
    t, x, y, psi, u, v = tr.t, tr['x'], tr['y'], tr['psi'], tr['u'], tr['v']
    dx, dy = np.gradient(x, t), np.gradient(y, t)
    cw = np.sqrt(np.mean((dx - (u * np.cos(psi) - v * np.sin(psi))) ** 2
                         + (dy - (u * np.sin(psi) + v * np.cos(psi))) ** 2))
    ccw = np.sqrt(np.mean((dx - (u * np.cos(psi) + v * np.sin(psi))) ** 2
                          + (dy - (-u * np.sin(psi) + v * np.cos(psi))) ** 2))
    assert cw < 0.06 and ccw > 2 * cw
    # + rudder turns to starboard: while the helm is held at +35 deg, r > 0
    held = tr['rudder'] > math.radians(30)
    assert held.sum() > 1000 and np.median(tr['r'][held]) > math.radians(1.5)


def test_true_wind_reproduces_the_relative_columns():
    """
    Trial.wind is the air's velocity toward north/east.

    With the ship's motion it gives the file's apparent wind at midship (the data set's own
    relation, ~1e-4 m/s).
    """
    cols, _ = esso.read_esso_table(TURN)
    tr = esso.read_esso_csv(TURN, keep_astern=True)[0]
    ua = np.empty(len(tr))
    ga = np.empty(len(tr))
    for k in range(len(tr)):
        ua[k], ga[k] = apparent_wind_ne(tr.wind[k, 0], tr.wind[k, 1], tr['psi'][k], tr['u'][k],
                                        tr['v'][k])
    rel_u = cols['wind_velo_relative_mid [m/s]']
    rel_g = cols['wind_dir_relative_mid [rad]']
    assert np.sqrt(np.mean((ua - rel_u) ** 2)) < 1e-3
    dvec = ua * np.exp(1j * ga) - rel_u * np.exp(1j * rel_g)
    assert np.sqrt(np.mean(np.abs(dvec) ** 2)) < 1e-3
    # and the same from the numpy helper of the reader
    ua2, _ = esso.apparent_wind(cols['wind_velo_true [m/s]'], cols['wind_dir_true [rad]'],
                                cols['psi_hat [rad]'], cols['u_velo [m/s]'],
                                cols['vm_velo [m/s]'])
    np.testing.assert_allclose(ua2, ua, atol=1e-9)


def test_trailing_nan_rows_trimmed_not_rejected():
    tr = load_trials(ZIGZAG_NAN, keep_astern=True)
    assert len(tr) == 1
    assert any('327 trailing' in n and 'trimmed' in n for n in tr[0].notes)
    assert tr[0].duration_s == pytest.approx(170.0, abs=0.2)


def _damaged(tmp_path, src, name, edit):
    lines = src.read_text().splitlines(keepends=True)
    p = tmp_path / name
    p.write_text(edit(lines))
    return p


@pytest.mark.parametrize('name,edit,usable', [
    ('cut_mid_line.csv', lambda ls: ''.join(ls[:400]) + ls[400][:25], True),
    ('nan_rows.csv', lambda ls: ''.join(ls[:100] + [',' * 12 + '\n'] * 3 + ls[100:200]
                                        + ['nan,' * 12 + 'nan\n'] + ls[200:300]), True),
    ('nan_state.csv', lambda ls: ''.join(ls[:50] + [ls[50].replace(',', ',nan,', 1)]
                                         + ls[51:300]), True),
    ('nan_state_field.csv', lambda ls: ''.join(
        ls[:50] + [','.join(['5.0', 'nan'] + ls[50].split(',')[2:])] + ls[51:300]), True),
    ('empty.csv', lambda ls: '', False),
    ('header_only.csv', lambda ls: ls[0], False),
    ('one_row.csv', lambda ls: ''.join(ls[:2]), False),
    ('all_nan.csv', lambda ls: ls[0] + (',' * 12 + '\n') * 20, False),
    ('text_in_numbers.csv', lambda ls: ''.join(ls[:30]) + 'a,b,c,d,e,f,g,h,i,j,k,l,m\n'
     + ''.join(ls[30:200]), True),
    ('time_gap.csv', lambda ls: ''.join(ls[:150] + ls[250:400]), True),
])
def test_damaged_copies_never_traceback(tmp_path, name, edit, usable):
    p = _damaged(tmp_path, TURN, name, edit)
    for keep in (True, False):
        try:
            trials = load_trials(p, keep_astern=keep)
        except MmgTunerError as exc:
            assert not usable or not keep, f'{name}: {exc}'
            assert str(p) in str(exc) or p.name in str(exc)
            continue
        assert usable
        for tr in trials:
            assert np.all(np.isfinite(tr.states)) and len(tr) >= 10


def test_folder_and_error_messages(tmp_path):
    d = tmp_path / 'runs'
    d.mkdir()
    shutil.copy(TURN, d / TURN.name)
    shutil.copy(ZIGZAG_NAN, d / ZIGZAG_NAN.name)
    assert len(load_trials(d, keep_astern=True)) == 2
    with pytest.raises(TrialDataError, match='no such file'):
        esso.read_esso(tmp_path / 'missing')
    bad = tmp_path / 'bad.csv'
    bad.write_bytes(b'\xff\xfe\x00garbage')
    with pytest.raises(MmgTunerError):
        load_trials(bad)
    assert not esso.is_esso_csv(bad)


def test_cut_from_event_starts_before_the_helm_order():
    tr = esso.read_esso_csv(TURN, keep_astern=True)[0]
    te = esso.event_time(tr)
    assert te == pytest.approx(119.9, abs=0.3)          # the +35 deg order, after the approach
    cut = esso.cut_from_event(tr, before_s=5.0)
    assert cut.t[0] == 0.0 and cut.start_s == pytest.approx(te - 5.0, abs=0.051)
    assert abs(cut['rudder'][0]) < math.radians(10)       # still on the approach
    assert cut['rudder'][80] > math.radians(30)           # over by 3 s after the event
    assert any('rudder_first_over' in n for n in cut.notes)
    # the zigzag's first order is its first +-15 deg hold, not the approach steering
    zz = esso.read_esso_csv(ZIGZAG_NAN, keep_astern=True)[0]
    ez = esso.event_time(zz)
    k = np.searchsorted(zz.t, ez)
    assert abs(zz['rudder'][k + 40]) > math.radians(10)
    with pytest.raises(TrialDataError, match='unknown event'):
        esso.cut_from_event(tr, event='nonsense')
    with pytest.raises(TrialDataError, match="event 'propeller_first_astern' not found"):
        esso.cut_from_event(tr, event='propeller_first_astern')
    be = esso.read_esso_csv(BERTHING, keep_astern=True)[0]
    cut = esso.cut_from_event(be, event='propeller_first_astern', before_s=2.0)
    assert cut['rpm'][0] >= 0 and cut['rpm'].min() < 0


def test_every_run_simulates_with_the_lowspeed_family():
    """
    All 33 runs simulate through the lowspeed family with the measured wind.

    All 33 runs, astern and u <= 0 kept, through the lowspeed family with the measured wind
    (api.load_trials' keep_astern pass-through): no failure, a finite index for each; the
    standard-model ships refuse the astern parts with a status, not NaN.
    """
    import mmg_tuner as mt
    ship = mt.load_ship('esso_osaka_3m')
    trials = mt.load_trials([DATA / k for k in ('turning', 'zigzag', 'random', 'berthing')],
                            keep_astern=True)
    assert len(trials) == 33 and all(t.wind is not None for t in trials)
    res = mt.evaluate(ship, trials, restart_every_s=100)
    # predicting every state's pooled mean scores 6; the published model ~1.1
    assert res.index_all is not None and res.index_all < 3.0
    for name, s in res.trials.items():
        assert s.failed_at_s is None and math.isfinite(s.index), name
    be = [t for t in trials if t.name == BERTHING.stem]
    kv = mt.evaluate(mt.load_ship('kvlcc2'), be, restart_every_s=0)
    s = kv.trials[BERTHING.stem]
    assert s.index is None and s.failed_at_s is not None and '<= 0' in s.failure


def test_load_trials_reads_the_data_folder_keeping_astern_by_family():
    """
    The whole data set reads from its top folder, astern kept by family.

    The whole data set from its top folder (kind subfolders found recursively, README and LICENSE
    skipped); astern propeller and u <= 0 kept because the lowspeed family simulates them, left out
    (with the note) for a standard-family ship, refused if forced on one.
    """
    import mmg_tuner as mt
    esso_ship, kvlcc2 = mt.load_ship('esso_osaka_3m'), mt.load_ship('kvlcc2')
    trials = mt.load_trials([DATA], ship=esso_ship)
    files = sorted(DATA.rglob('*.csv'), key=lambda p: (p.parent.name, p.name))
    assert [t.name for t in trials] == [p.stem for p in files]
    be = next(t for t in trials if t.name == BERTHING.stem)
    assert be['rpm'].min() < 0 and be['u'].min() < 0
    split = mt.load_trials([BERTHING], ship=kvlcc2)
    assert len(split) > 1 and all(t['rpm'].min() > 0 and t['u'].min() > 0 for t in split)
    assert any('left out' in n for n in split[0].notes)
    assert mt.load_trials([BERTHING])[0]['rpm'].min() > 0       # no ship: as before
    with pytest.raises(MmgTunerError, match='keep_astern=True.*standard'):
        mt.load_trials([BERTHING], ship=kvlcc2, keep_astern=True)


class _Loaded(MmgTunerError):
    pass


@pytest.mark.parametrize('name', ['tune', 'diagnose', 'evaluate'])
def test_commands_pass_the_event_cut_and_keep_astern_to_load_trials(tmp_path, monkeypatch,
                                                                    name):
    import importlib

    import mmg_tuner.api as api
    seen = {}

    def fake(paths, **kw):
        seen.update(kw)
        raise _Loaded('stop here')
    monkeypatch.setattr(api, 'load_trials', fake)
    mod = importlib.import_module(f'mmg_tuner.cli.{name}')
    with pytest.raises(_Loaded):
        mod.command([str(TURN), '--ship', 'esso_osaka_3m', '--out', str(tmp_path / 'o'),
                     '--cut-from-event', 'rudder_first_over:4'])
    assert seen['cut_from_event'] == 'rudder_first_over:4'
    assert seen.get('keep_astern') is None      # the ship's family decides (load_trials)
    with pytest.raises(MmgTunerError, match='cut-from-event'):
        mod.command([str(TURN), '--out', str(tmp_path / 'p'), '--cut-from-event', 'bogus'])


def test_cut_from_event_in_the_api_and_inspect(capsys):
    import mmg_tuner as mt
    from mmg_tuner.cli import inspect
    ship = mt.load_ship('esso_osaka_3m')
    (whole,) = mt.load_trials(TURN, ship=ship)
    te = esso.event_time(whole)
    (cut,) = mt.load_trials(TURN, ship=ship, cut_from_event='rudder_first_over:5')
    assert cut.t[0] == 0.0 and cut.start_s == pytest.approx(te - 5.0, abs=0.051)
    (cut2,) = mt.load_trials(TURN, ship=ship, cut_from_event=('rudder_first_over', 5))
    np.testing.assert_array_equal(cut2.states, cut.states)
    (kept,) = mt.load_trials(TURN, ship=ship, cut_from_event='propeller_first_astern')
    assert len(kept) == len(whole) and any(n.startswith('not cut') for n in kept.notes)
    with pytest.raises(MmgTunerError, match='rudder_first_over'):
        mt.load_trials(TURN, ship=ship, cut_from_event='nonsense:5')
    assert inspect.command([str(TURN), '--ship', 'esso_osaka_3m', '--cut-from-event',
                            'rudder_first_over']) == 0
    out = capsys.readouterr().out
    assert 'cut from 5 s before rudder_first_over' in out
    assert f'{cut.duration_s:.1f} s at dt 0.1 s' in out


def test_split_holds_out_every_run_exactly_once_and_fold_1_is_the_tables_split():
    """The benchmarks' split rule (data.esso): fold 1 holds out 4/2/3/2 runs, each run once."""
    by_kind = esso.runs_by_kind()
    assert {k: len(v) for k, v in by_kind.items()} == {
        'turning': 12, 'zigzag': 7, 'random': 8, 'berthing': 5}   # 32: a turn_cut_ copy dropped
    held1 = {k: esso.split_runs(v)[1] for k, v in by_kind.items()}
    assert {k: len(v) for k, v in held1.items()} == {
        'turning': 4, 'zigzag': 2, 'random': 3, 'berthing': 2}
    for kind, files in by_kind.items():
        held = [esso.split_runs(files, f)[1] for f in esso.FOLDS]
        assert sorted(f for h in held for f in h) == sorted(files), kind   # each exactly once
        assert held[1] == files[1::3], kind
        for h in held:
            assert esso.split_runs(files, esso.FOLDS[held.index(h)])[0] == [
                x for x in files if x not in h]
        assert esso.split_runs(files, None) == (files, [])


def test_runs_by_kind_drops_a_cut_copy_only_beside_its_whole_run(tmp_path):
    for name in ('turning/turn_a.csv', 'turning/turn_cut_a.csv', 'turning/turn_cut_b.csv',
                 'zigzag/z.csv'):
        (tmp_path / name).parent.mkdir(exist_ok=True)
        (tmp_path / name).write_text('')
    got = {k: [f.name for f in v] for k, v in esso.runs_by_kind(tmp_path).items()}
    assert got == {'turning': ['turn_a.csv', 'turn_cut_b.csv'], 'zigzag': ['z.csv'],
                   'random': [], 'berthing': []}


def test_load_split_cuts_manoeuvres_and_keeps_the_others_whole():
    train, test, kind_of = esso.load_split(1)
    assert (len(train), len(test)) == (21, 11)
    assert set(kind_of) == {t.name for t in train + test}
    for tr in train + test:
        cut = any('cut from' in n for n in tr.notes)
        assert cut == (kind_of[tr.name] in ('turning', 'zigzag')), tr.name
