"""
The documentation: the README a newcomer reads and the Sphinx site in doc/.

The site is built with warnings as errors (a broken link, a missing page or reference, a bad
directive fails), the guides' code blocks marked ``# runnable`` are run, and the README's
promises (its size, its two set-up commands, its table of commands, its links) are checked
against the files they describe.
"""
import importlib.util
import os
from pathlib import Path
import re
import shlex
import subprocess
import sys

import mmg_tuner as mt
import pytest

ROOT = Path(__file__).resolve().parents[2]
DOC = ROOT / 'doc'
README = ROOT / 'README.md'
LINK = re.compile(r'\[[^\]]*\]\(([^)\s]+)\)')


def _console_scripts() -> set[str]:
    return set(re.findall(r"'(\w+) = mmg_tuner\.[\w.]+:main'", (ROOT / 'setup.py').read_text()))


def _section(text: str, heading: str) -> str:
    start = text.index(heading)
    end = text.find('\n## ', start + len(heading))
    return text[start:] if end < 0 else text[start:end]


def _fenced(text: str, lang: str) -> list[str]:
    return re.findall(rf'^```{lang}\n(.*?)^```', text, flags=re.M | re.S)


def test_readme_is_short():
    assert README.stat().st_size < 10_000, 'README.md must stay under 10 KB: move detail to doc/'


def test_readme_setup_is_the_two_commands_ci_runs():
    setup = _fenced(_section(README.read_text(), '## Set-up'), 'bash')[0]
    commands = [line.split('#')[0].strip() for line in setup.strip().split('\n')]
    assert commands == ['bash scripts/setup.sh', 'bash scripts/test.sh']
    assert all((ROOT / c.split()[1]).is_file() for c in commands)
    assert 'scripts/test.sh' in (ROOT / '.ci' / 'run').read_text()


def test_readme_command_table_matches_the_installed_executables():
    table = _section(README.read_text(), '## Commands')
    listed = re.findall(r'^\| `(\w+)` \|', table, flags=re.M)
    assert len(listed) == len(set(listed))
    assert set(listed) == _console_scripts()


def test_every_command_has_its_generated_reference():
    page = (DOC / 'reference' / 'commands.md').read_text()
    documented = set(re.findall(r'^```\{mmg-command-help\} (\w+)$', page, flags=re.M))
    cli = {p.stem for p in (ROOT / 'mmg_tuner' / 'cli').glob('*.py')
           if 'def build_parser' in p.read_text()}
    assert documented == cli == _console_scripts() - {'sim_node', 'replay_node'}


def test_readme_python_example_uses_only_the_public_api():
    code = _fenced(README.read_text(), 'python')[0]
    compile(code, 'README.md', 'exec')
    used = set(re.findall(r'\bmt\.(\w+)', code))
    assert used and used <= set(mt.__all__)


def _command_lines():
    """Yield (page, line) for each documented command line: bash blocks, one command a line."""
    commands = _console_scripts() - {'sim_node', 'replay_node'}
    for page in [README, *sorted(DOC.rglob('*.md'))]:
        for block in _fenced(page.read_text(), 'bash'):
            for line in block.replace('\\\n', ' ').split('\n'):
                words = shlex.split(line.split(' #')[0])
                if words[:3] == ['ros2', 'run', 'mmg_tuner']:
                    words = words[3:]
                # TRIALS... and the like are placeholders, not arguments
                if words and words[0] in commands and not any('...' in w for w in words):
                    yield page, words


def test_documented_command_lines_parse():
    lines = list(_command_lines())
    assert len({words[0] for _, words in lines}) >= 6, 'the command examples went missing'
    for page, words in lines:
        parser = importlib.import_module(f'mmg_tuner.cli.{words[0]}').build_parser()
        try:
            parser.parse_args(words[1:])
        except Exception as e:   # the commands' parser raises UsageError, never exits
            pytest.fail(f'{page.relative_to(ROOT)}: {shlex.join(words)}: {e}')


@pytest.mark.parametrize('page', [README, *sorted(DOC.rglob('*.md'))],
                         ids=lambda p: str(p.relative_to(ROOT)))
def test_relative_links_resolve(page):
    # Sphinx checks doc/ links too, but only where Sphinx is installed; the README it never sees
    text = re.sub(r'^```.*?^```', '', page.read_text(), flags=re.M | re.S)
    broken = [t for t in LINK.findall(text)
              if not re.match(r'[a-z]+:', t) and not t.startswith('#')
              and not (page.parent / t.split('#')[0]).exists()]
    assert not broken, f'{page}: links to missing files: {broken}'


def test_site_builds_without_warnings(tmp_path):
    for module in ('sphinx', 'myst_parser'):
        if importlib.util.find_spec(module) is None:
            pytest.skip(f'{module} is not installed (requirements.txt has it): '
                        'the documentation site is not built')
    env = dict(os.environ, NUMBA_NUM_THREADS=os.environ.get('NUMBA_NUM_THREADS', '1'))
    run = subprocess.run([sys.executable, '-m', 'sphinx', '-W', '--keep-going', '-q', '-b',
                          'html', str(DOC), str(tmp_path / 'html')],
                         cwd=ROOT, env=env, capture_output=True, text=True, timeout=300)
    assert run.returncode == 0, run.stderr[-5000:]
    assert (tmp_path / 'html' / 'index.html').is_file()
    commands = (tmp_path / 'html' / 'reference' / 'commands.html').read_text()
    assert '--max-evals' in commands          # generated from tune's parser
    nodes = (tmp_path / 'html' / 'reference' / 'nodes.html').read_text()
    assert 'real_time_factor' in nodes and 'trial_index' in nodes


def _runnable_blocks():
    for page in sorted(DOC.rglob('*.md')):
        for i, code in enumerate(_fenced(page.read_text(), 'python')):
            if code.startswith('# runnable\n'):
                yield pytest.param(code, id=f'{page.relative_to(DOC)}[{i}]')


@pytest.mark.parametrize('code', list(_runnable_blocks()))
def test_runnable_code_blocks(code, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    exec(compile(code, 'doc', 'exec'), {'__name__': '__doc_block__'})


def test_there_are_runnable_blocks():
    assert list(_runnable_blocks()), 'no guide block is marked "# runnable"'
