"""Type checking: mypy on the package as mypy.ini configures it (mmg_tuner/core for now)."""
import importlib.util
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]


@pytest.mark.linter
def test_mypy(monkeypatch):
    if importlib.util.find_spec('mypy') is None:
        pytest.skip('mypy is not installed (requirements.txt has it): the package is not '
                    'type-checked')
    from mypy import api
    monkeypatch.chdir(ROOT)   # mypy.ini's files and cache_dir are relative to the root
    out, err, status = api.run(['--config-file', str(ROOT / 'mypy.ini')])
    assert status == 0, out + err
