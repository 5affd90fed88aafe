"""
The benchmark suite's command line: ``python -m bench list`` and ``python -m bench run NAME``.

Every module of bench/ must be a listed benchmark (so none is forgotten by the generated page),
and a run must write its figures as JSON with the machine, the commit, the date and the command,
never over the committed results when told to write elsewhere.
"""
import ast
import json
import os
from pathlib import Path
import re
import subprocess
import sys

import pytest

ROOT = Path(__file__).resolve().parents[2]
BENCH = ROOT / 'bench'


def _bench(*args, timeout=600):
    env = dict(os.environ, NUMBA_NUM_THREADS=os.environ.get('NUMBA_NUM_THREADS', '1'))
    return subprocess.run([sys.executable, '-m', 'bench', *args], cwd=ROOT, env=env,
                          capture_output=True, text=True, timeout=timeout)


def _modules() -> set[str]:
    return {p.stem for p in BENCH.glob('*.py') if not p.name.startswith('_')}


def test_list_names_every_module_with_its_docstring_line():
    res = _bench('list')
    assert res.returncode == 0, res.stderr
    listed = {}
    for line in res.stdout.splitlines():
        name, _, desc = line.partition(' ')
        listed[name] = desc.strip()
    assert set(listed) == _modules()   # a module without benchmark() would be missing here
    for name, desc in listed.items():
        doc = ast.get_docstring(ast.parse((BENCH / f'{name}.py').read_text()))
        assert desc and desc == ' '.join(doc.strip().split('\n\n')[0].split()), name


def test_every_benchmark_has_the_entry_point_and_no_path_hack():
    for name in _modules():
        src = (BENCH / f'{name}.py').read_text()
        tree = ast.parse(src)
        fn = next(n for n in tree.body
                  if isinstance(n, ast.FunctionDef) and n.name == 'benchmark')
        assert [a.arg for a in fn.args.args] == ['quick', 'argv'], name
        assert 'sys.path' not in src, name   # run from the root: python -m bench run NAME


def test_run_unknown_name_fails_naming_the_choices():
    res = _bench('run', 'no_such_bench')
    assert res.returncode == 2 and 'no_such_bench' in res.stderr and 'bench_tune' in res.stderr


def test_quick_run_writes_json_with_its_provenance_elsewhere_when_told(tmp_path):
    committed = BENCH / 'results' / 'tug_twin.json'
    before = committed.read_bytes() if committed.exists() else None
    res = _bench('run', 'tug_twin', '--quick', '--results-dir', str(tmp_path))
    assert res.returncode == 0, res.stderr[-3000:]
    doc = json.loads((tmp_path / 'tug_twin.json').read_text())
    assert doc['name'] == 'tug_twin' and doc['quick'] is True and doc['argv'] == []
    assert doc['command'] == f'python -m bench run tug_twin --quick --results-dir {tmp_path}'
    head = subprocess.run(['git', '-C', str(ROOT), 'rev-parse', 'HEAD'], capture_output=True,
                          text=True).stdout.strip()
    assert doc['commit'] == head and isinstance(doc['dirty'], bool)
    assert doc['date'].endswith('+00:00') and doc['wall_s'] > 0
    m = doc['machine']
    assert m['cores'] == os.cpu_count() and m['cpu'] and m['python'] and m['numba']
    # the figures are the benchmark's own: three models' steady speeds at 3, 5, 7, 10 rev/s
    speeds = doc['figures']['steady_surge_speed_ms']
    assert [r['model'] for r in speeds] == ['Table 3, Pedersen C', 'Table 3, Fossen C',
                                            'Table 4 (6 coef.)']
    for r in speeds:
        u = [r[f'{n} rev/s'] for n in (3, 5, 7, 10)]
        assert all(0 < a < b for a, b in zip(u, u[1:])), r   # faster with more shaft speed
    assert doc['figures']['otter_u_ms_at_10_rps'] == pytest.approx(1.128, abs=0.01)
    after = committed.read_bytes() if committed.exists() else None
    assert after == before   # the committed results are untouched


def test_hand_copied_results_name_their_source_and_a_benchmark():
    files = sorted((BENCH / 'results' / 'hand_copied').glob('*.json'))
    assert files
    for f in files:
        doc = json.loads(f.read_text())
        assert doc['name'] == f.stem and f.stem in _modules(), f
        # copied by hand: from the README's history, or from a registered run's printout
        assert doc['source'].startswith(('hand-copied from the README history, commit',
                                         'copied from the registered run')), f
        assert doc['commit'] and doc['commit'] in doc['source'], f
        assert doc['notes'].strip(), f


def test_documented_bench_commands_name_a_benchmark():
    """``python -m bench run NAME`` in the documentation and the benchmarks' own texts."""
    pages = [*sorted((ROOT / 'doc').rglob('*.md')), *sorted(BENCH.glob('*.py'))]
    found = {}
    for page in pages:
        for name in re.findall(r'python -m bench run ([a-z_0-9]+)', page.read_text()):
            found.setdefault(name, page)
    assert len(found) >= 10, 'the documented bench commands went missing'
    unknown = {n: str(p.relative_to(ROOT)) for n, p in found.items() if n not in _modules()}
    assert not unknown, unknown


def test_figures_become_plain_json():
    import numpy as np
    from bench import plain
    got = plain({'a': np.float64(0.5), 2: (np.int64(3), np.array([1.5, np.inf])),
                 'p': ROOT, 'n': float('nan')}, nan=None)
    assert got == {'a': 0.5, '2': [3, [1.5, None]], 'p': str(ROOT), 'n': None}
    assert json.loads(json.dumps(got, allow_nan=False)) == got
    assert plain([np.float32(np.nan)])[0] != plain([np.float32(np.nan)])[0]   # YAML keeps NaN
