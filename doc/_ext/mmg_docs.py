"""
Sphinx directives that generate the reference from the code, so it cannot drift from it.

``mmg-command-help NAME``: the ``--help`` of command NAME, from the argparse parser that
``mmg_tuner.cli.NAME.build_parser`` returns (the same parser the command runs).

``mmg-node-params MODULE``: a table of a node's ROS parameters (default, range, read-only,
description with units) from the ``PARAMS`` table that ``MODULE`` declares its parameters from.
"""
import importlib
import os

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


def setup(app):
    """Register the directives."""
    app.add_directive('mmg-command-help', CommandHelp)
    app.add_directive('mmg-node-params', NodeParams)
    return {'parallel_read_safe': True, 'parallel_write_safe': True}
