"""
The benchmark suite, run from the repository root.

    python -m bench list                                  every benchmark and what it measures
    python -m bench run NAME [--quick] [--results-dir D] [ARGS...]

A benchmark is a module of this package (no leading underscore) that defines
``benchmark(quick: bool, argv: list[str]) -> dict``: it takes the benchmark's own command-line
arguments (``ARGS``; ``--quick`` selects a small budget, arguments given after it still win),
prints what it measures as it goes, and returns its figures: a mapping of figure names to
numbers or strings, or to a list of rows (dicts with the same keys) for a table. The first
paragraph of the module's docstring is its one-line description. :func:`run_benchmark` writes
the figures, with the machine, the commit, the date and the command, to
``bench/results/NAME.json``, from which the documentation's benchmark page is generated.

Modules are found by reading the files (``ast``), not by importing them, so ``list`` is fast and
does not load JAX or rclpy.
"""
from __future__ import annotations

import ast
from dataclasses import dataclass
import datetime as dt
import importlib
from importlib import metadata
import json
import math
import os
from pathlib import Path
import platform
import shlex
import subprocess
import time

BENCH_DIR = Path(__file__).resolve().parent
ROOT = BENCH_DIR.parent
RESULTS_DIR = BENCH_DIR / 'results'
HAND_COPIED_DIR = RESULTS_DIR / 'hand_copied'
"""Figures typed by hand in the README's history before the suite wrote JSON, one file per
benchmark; kept as the provenance of each benchmark (never written by a run)."""
ENTRY_POINT = 'benchmark'
SCHEMA = 1


@dataclass(frozen=True)
class Benchmark:
    """One benchmark module: its name (the file name without .py) and what it measures."""

    name: str
    description: str
    path: Path


def _description(doc: str | None) -> str:
    """Return the first paragraph of a docstring on one line."""
    para = (doc or '').strip().split('\n\n')[0]
    return ' '.join(para.split())


def benchmarks() -> dict[str, Benchmark]:
    """Return every benchmark of this package by name, found by reading the module files."""
    out = {}
    for path in sorted(BENCH_DIR.glob('*.py')):
        if path.name.startswith('_'):
            continue
        tree = ast.parse(path.read_text(), str(path))
        if any(isinstance(n, ast.FunctionDef) and n.name == ENTRY_POINT for n in tree.body):
            out[path.stem] = Benchmark(path.stem, _description(ast.get_docstring(tree)), path)
    return out


def _version(dist: str) -> str | None:
    try:
        return metadata.version(dist)
    except metadata.PackageNotFoundError:
        return None


def machine() -> dict:
    """Return what the figures were measured on: CPU model, cores, Python and library versions."""
    cpu = platform.processor() or platform.machine()
    try:
        for line in Path('/proc/cpuinfo').read_text().splitlines():
            if line.startswith('model name'):
                cpu = line.split(':', 1)[1].strip()
                break
    except OSError:
        pass
    return {'cpu': cpu, 'cores': os.cpu_count(), 'system': platform.platform(),
            'python': platform.python_version(), 'numba': _version('numba'),
            'numpy': _version('numpy'),
            'numba_num_threads': os.environ.get('NUMBA_NUM_THREADS')}


def git_state(root: Path = ROOT) -> dict:
    """
    Return the checkout's commit and whether its tree differs from it.

    Result files are left out of the dirty check: an earlier run's uncommitted JSON does not
    change what is measured.
    """
    def git(*args: str) -> str | None:
        try:
            return subprocess.run(['git', '-C', str(root), *args], capture_output=True,
                                  text=True, check=True).stdout.strip()
        except (OSError, subprocess.CalledProcessError):
            return None
    commit = git('rev-parse', 'HEAD')
    status = git('status', '--porcelain', '--', '.', f':!{RESULTS_DIR.relative_to(root)}')
    return {'commit': commit, 'dirty': None if status is None else bool(status)}


def plain(value, nan=math.nan):
    """
    Return value as plain data for JSON or YAML: dicts, lists, numbers, strings.

    numpy scalars and arrays become numbers and lists, tuples lists, mapping keys strings,
    anything else (a path) its string; a non-finite float becomes ``nan`` (JSON has none).
    """
    if isinstance(value, dict):
        return {str(k): plain(v, nan) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [plain(v, nan) for v in value]
    if hasattr(value, 'tolist'):      # numpy scalars and arrays
        return plain(value.tolist(), nan)
    if isinstance(value, float) and not math.isfinite(value):
        return value if nan is math.nan else nan
    if value is None or isinstance(value, (bool, int, float, str)):
        return value
    return str(value)


def run_benchmark(name: str, quick: bool = False, argv: list[str] | None = None,
                  results_dir: Path = RESULTS_DIR, command: str | None = None) -> Path:
    """
    Run benchmark ``name`` and write its figures to ``results_dir/NAME.json``; return the path.

    The file is written atomically, only when the benchmark completes, so an interrupted run
    leaves the previous result in place.
    """
    from mmg_tuner._atomic import write_atomic   # here: `list` need not import the package
    known = benchmarks()
    if name not in known:
        raise KeyError(f'no benchmark {name!r} in {BENCH_DIR} (python -m bench list: '
                       f'{", ".join(known)})')
    argv = list(argv or [])
    if command is None:
        command = shlex.join(['python', '-m', 'bench', 'run', name]
                             + (['--quick'] if quick else []) + argv)
    started = dt.datetime.now(dt.timezone.utc)
    state = git_state()
    t0 = time.perf_counter()
    module = importlib.import_module(f'bench.{name}')
    figures = getattr(module, ENTRY_POINT)(quick, argv)
    doc = {'schema': SCHEMA, 'name': name, 'description': known[name].description,
           'command': command, 'quick': quick, 'argv': argv,
           'date': started.isoformat(timespec='seconds'),
           'wall_s': round(time.perf_counter() - t0, 1), **state, 'machine': machine(),
           'figures': plain(figures or {}, nan=None)}
    path = Path(results_dir) / f'{name}.json'
    write_atomic(path, json.dumps(doc, indent=1, ensure_ascii=False) + '\n')
    return path
