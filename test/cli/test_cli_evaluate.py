"""The evaluate command on bad output folders: its messages point at options it has."""
from mmg_tuner.cli import evaluate as cli_evaluate
import pytest


def test_used_out_is_refused_without_a_missing_resume(tmp_path, monkeypatch, capsys):
    """Evaluate has no --resume: its refusal of a used --out must not suggest one."""
    out = tmp_path / 'ev'
    out.mkdir()
    (out / 'evaluate.json').write_text('{}')

    def boom(*a, **k):
        raise AssertionError('the work started')
    monkeypatch.setattr(cli_evaluate.api, 'load_trials', boom)
    with pytest.raises(SystemExit) as exc:
        cli_evaluate.main([str(tmp_path / 'none.csv'), '--out', str(out)])
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert err.startswith('ERROR: --out') and 'not empty' in err, err
    assert '--resume' not in err
    assert '--resume' not in cli_evaluate.build_parser().format_help()
    assert (out / 'evaluate.json').read_text() == '{}'
