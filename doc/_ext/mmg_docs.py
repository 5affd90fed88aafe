"""
Sphinx directives that generate the reference from the code, so it cannot drift from it.

``mmg-command-help NAME``: the ``--help`` of command NAME, from the argparse parser that
``mmg_tuner.cli.NAME.build_parser`` returns (the same parser the command runs).

``mmg-node-params MODULE``: a table of a node's ROS parameters (default, range, read-only,
description with units) from the ``PARAMS`` table that ``MODULE`` declares its parameters from.

``mmg-benchmarks``: one section per benchmark of ``python -m bench list``, from the JSON its
last run wrote to ``bench/results/NAME.json`` (figures, machine, commit, date, command) and the
figures hand-copied from the README's history (``bench/results/hand_copied/NAME.json``).
"""
import importlib
import json
import os
from pathlib import Path

from docutils import nodes
from docutils.statemachine import StringList
from sphinx.util.docutils import SphinxDirective

# argparse wraps --help at $COLUMNS: fix it so the page is the same on every machine
HELP_COLUMNS = '96'


class CommandHelp(SphinxDirective):
    """The ``--help`` text of one command, under a heading with the command's name."""

    required_arguments = 1

    def run(self):
        name = self.arguments[0]
        module = importlib.import_module(f'mmg_tuner.cli.{name}')
        old = os.environ.get('COLUMNS')
        os.environ['COLUMNS'] = HELP_COLUMNS
        try:
            parser = module.build_parser()
            parser.prog = name
            text = parser.format_help()
        finally:
            if old is None:
                del os.environ['COLUMNS']
            else:
                os.environ['COLUMNS'] = old
        lines = [f'### `{name}`', '', '```text', *text.rstrip().split('\n'), '```', '']
        return self._parse(lines)

    def _parse(self, lines):
        holder = nodes.Element()
        self.state.nested_parse(StringList(lines, source=f'<{self.name}>'), self.content_offset,
                                holder, match_titles=True)
        return list(holder.children)


def _cell(value) -> str:
    return str(value).replace('|', '\\|').replace('\n', ' ')


class NodeParams(SphinxDirective):
    """A table of a node's parameters from the module's ``PARAMS`` mapping of ``Param``."""

    required_arguments = 1

    def run(self):
        module = importlib.import_module(self.arguments[0])
        rows = ['| parameter | default | range | read-only | description |',
                '|---|---|---|---|---|']
        for name, p in module.PARAMS.items():
            rng = '' if p.range is None else f'{p.range[0]:g} – {p.range[1]:g}'
            desc = p.description + (f' ({p.constraints})' if p.constraints else '')
            rows.append(f'| `{name}` | `{p.default!r}` | {rng} | '
                        f"{'yes' if p.read_only else ''} | {_cell(desc)} |")
        holder = nodes.Element()
        self.state.nested_parse(StringList(rows, source=f'<{self.name}>'), self.content_offset,
                                holder)
        return list(holder.children)


def _value(v) -> str:
    """Return one figure as table-cell text: 4 significant digits, lists and mappings inline."""
    if v is None:
        return '–'
    if isinstance(v, bool):
        return 'yes' if v else 'no'
    if isinstance(v, float):
        return f'{v:.4g}'
    if isinstance(v, list):
        return ', '.join(_value(x) for x in v) or '–'
    if isinstance(v, dict):
        return '; '.join(f'{k}: {_value(x)}' for k, x in v.items()) or '–'
    return _cell(v)


def _table(rows: list[dict], first: str | None = None) -> list[str]:
    """Return a Markdown table of rows (dicts); columns in order of first appearance."""
    cols = [] if first is None else [first]
    for r in rows:
        cols += [c for c in r if c not in cols]
    return (['| ' + ' | '.join(_cell(c) for c in cols) + ' |', '|' + '---|' * len(cols)]
            + ['| ' + ' | '.join(_value(r.get(c)) for c in cols) + ' |' for r in rows] + [''])


def _is_rows(v) -> bool:
    return isinstance(v, list) and bool(v) and all(isinstance(x, dict) for x in v)


def _is_keyed_rows(v) -> bool:
    return isinstance(v, dict) and bool(v) and all(isinstance(x, dict) for x in v.values())


def figure_lines(figures: dict) -> list[str]:
    """
    Return the Markdown of a run's figures.

    Numbers, strings and short lists or mappings go into one "figure | value" table; a list
    of rows (dicts) or a mapping of rows becomes a table of its own under the figure's name;
    a text of several lines (a printed summary) a text block.
    """
    plain = {k: v for k, v in figures.items()
             if not (_is_rows(v) or _is_keyed_rows(v) or (isinstance(v, str) and '\n' in v))}
    lines = _table([{'figure': k, 'value': v} for k, v in plain.items()]) if plain else []
    for k, v in figures.items():
        if _is_rows(v):
            lines += [f'**{_cell(k)}**', ''] + _table(v)
        elif _is_keyed_rows(v):
            lines += [f'**{_cell(k)}**', ''] + _table([{'': n, **r} for n, r in v.items()])
        elif isinstance(v, str) and '\n' in v:
            lines += [f'**{_cell(k)}**', '', '```text', *v.rstrip().split('\n'), '```', '']
    return lines


def run_lines(doc: dict) -> list[str]:
    """Return the Markdown of one result file: where, when and how it ran, then its figures."""
    m = doc.get('machine', {})
    commit = (doc.get('commit') or 'unknown')[:10] + (' (with uncommitted changes)'
                                                      if doc.get('dirty') else '')
    meta = [{'': 'command', 'value': f"`{doc.get('command')}`"},
            {'': 'quick', 'value': 'yes: a smaller budget where the benchmark has one (its '
             'docstring says), so not its full figures' if doc.get('quick') else 'no'},
            {'': 'date (UTC)', 'value': doc.get('date')},
            {'': 'commit', 'value': commit},
            {'': 'machine', 'value': f"{m.get('cpu')}, {m.get('cores')} cores; Python "
             f"{m.get('python')}, numba {m.get('numba')}, numpy {m.get('numpy')}; "
             f"NUMBA_NUM_THREADS={m.get('numba_num_threads') or 'unset'}"},
            {'': 'wall time', 'value': f"{doc.get('wall_s')} s"}]
    rows = ['|  | value |', '|---|---|'] + [f"| {r['']} | {r['value']} |" for r in meta] + ['']
    return rows + figure_lines(doc.get('figures', {}))


def benchmark_lines(name: str, description: str, results: Path) -> list[str]:
    """Return the section of one benchmark."""
    lines = [f'## `{name}`', '', description, '', f'Run: `python -m bench run {name}`', '']
    latest = results / f'{name}.json'
    if latest.is_file():
        lines += ['### Latest run', ''] + run_lines(json.loads(latest.read_text()))
    else:
        lines += [f'Not run yet: `python -m bench run {name}`.', '']
    old = results / 'hand_copied' / f'{name}.json'
    if old.is_file():
        doc = json.loads(old.read_text())
        lines += ['### Earlier figures (hand-copied)', '', f"Source: {doc['source']}.", '',
                  *doc['notes'].rstrip().split('\n'), '']
    return lines


class Benchmarks(SphinxDirective):
    """Every benchmark of ``bench/`` with its latest results and its hand-copied history."""

    def run(self):
        bench = importlib.import_module('bench')
        results = Path(bench.RESULTS_DIR)
        lines = []
        for b in bench.benchmarks().values():
            self.env.note_dependency(str(b.path))
            for f in (results / f'{b.name}.json', results / 'hand_copied' / f'{b.name}.json'):
                if f.is_file():
                    self.env.note_dependency(str(f))
            lines += benchmark_lines(b.name, b.description, results)
        holder = nodes.Element()
        self.state.nested_parse(StringList(lines, source='<mmg-benchmarks>'),
                                self.content_offset, holder, match_titles=True)
        return list(holder.children)


def setup(app):
    """Register the directives."""
    app.add_directive('mmg-command-help', CommandHelp)
    app.add_directive('mmg-node-params', NodeParams)
    app.add_directive('mmg-benchmarks', Benchmarks)
    return {'parallel_read_safe': True, 'parallel_write_safe': True}
