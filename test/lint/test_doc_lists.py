"""
The documentation's lists that can drift from the code: families, actuators, commands, effects.

``doc/reference/layout.md`` lists every model family (with its actuators and its ship configs),
every actuator model and every command; ``doc/reference/commands.md`` every command. Each list
is read from its Markdown table and compared with what the code registers, both ways: a family,
actuator, ship config or command added without its row, or a row left for one removed, fails.
The concept pages ``doc/concepts/families.md`` and ``doc/concepts/actuators.md`` describe each
family and actuator in a bullet of their own, under a count written in words; both are checked
the same way, and ``doc/concepts/effects.md``'s table against the effects library. No Sphinx
build: these run in a second.
"""
from pathlib import Path
import re

from mmg_tuner.core import actuators, effects, models
import yaml

ROOT = Path(__file__).resolve().parents[2]
LAYOUT = ROOT / 'doc' / 'reference' / 'layout.md'
COMMANDS = ROOT / 'doc' / 'reference' / 'commands.md'
FAMILIES = ROOT / 'doc' / 'concepts' / 'families.md'
ACTUATORS = ROOT / 'doc' / 'concepts' / 'actuators.md'
EFFECTS = ROOT / 'doc' / 'concepts' / 'effects.md'
NUMBERS = ('zero', 'one', 'two', 'three', 'four', 'five', 'six', 'seven', 'eight', 'nine', 'ten',
           'eleven', 'twelve')


def _console_scripts() -> dict[str, str]:
    """Return setup.py's console scripts: command -> module."""
    return dict(re.findall(r"'(\w+) = (mmg_tuner\.[\w.]+):main'",
                           (ROOT / 'setup.py').read_text()))


def _rows(text: str, header: str) -> dict[str, list[str]]:
    """Return a Markdown table's rows by the backticked name of their first cell."""
    start = text.index(header)
    rows: dict[str, list[str]] = {}
    for line in text[start:].split('\n')[2:]:
        if not line.startswith('|'):
            break
        cells = [c.strip() for c in line.strip().strip('|').split('|')]
        name = re.fullmatch(r'`(\w+)`', cells[0])
        assert name, f'{line!r}: the first cell is not a `name`'
        assert name.group(1) not in rows, f'{name.group(1)} is listed twice'
        rows[name.group(1)] = cells[1:]
    return rows


def _words(cell: str) -> set[str]:
    return set(re.findall(r'\w+', cell))


def _ship_configs() -> dict[str, str]:
    """Return config/NAME.yaml -> its family, for every ship config (a top-level ``model:``)."""
    out = {}
    for p in sorted((ROOT / 'config').glob('*.yaml')):
        doc = yaml.safe_load(p.read_text())
        if isinstance(doc, dict) and isinstance(doc.get('model'), str):
            out[p.stem] = doc['model']
    return out


def test_layout_lists_every_family_with_its_actuators_and_ship_configs():
    rows = _rows(LAYOUT.read_text(), '| family | actuators |')
    assert list(rows) == list(models.BUILTIN), 'layout.md: the families, in BUILTIN order'
    configs = _ship_configs()
    assert set(configs.values()) <= set(models.BUILTIN)
    for name, (acts, ships, _) in rows.items():
        assert _words(acts) == set(models.family(name).actuators), f'{name}: its actuators'
        assert _words(ships) == {c for c, f in configs.items() if f == name}, \
            f'{name}: its ship configs in config/'


def test_layout_lists_every_actuator_with_its_channels():
    rows = _rows(LAYOUT.read_text(), '| actuator | input channels |')
    assert set(rows) == set(actuators.BUILTIN), 'layout.md: the actuator models'
    for name, (channels, _) in rows.items():
        assert _words(channels) == set(actuators.actuator(name).inputs), f'{name}: its channels'


def test_layout_lists_every_command_with_its_module():
    rows = _rows(LAYOUT.read_text(), '| command | module |')
    scripts = _console_scripts()
    assert set(rows) == set(scripts), 'layout.md: the commands of setup.py'
    for name, (module,) in rows.items():
        assert module == f"`{scripts[name].replace('.', '/')}.py`", f'{name}: its module'


def test_commands_page_lists_every_command():
    rows = _rows(COMMANDS.read_text(), '| command | what it does |')
    assert set(rows) == set(_console_scripts()), 'commands.md: the commands of setup.py'


def _bullets(text: str, pattern: str) -> list[str]:
    """Return the names of the top-level bullets that open with ``pattern``'s name, in order."""
    return re.findall(rf'^- {pattern}', text, flags=re.M)


def _count(text: str, phrase: str) -> int:
    """Return the number written in words before ``phrase`` (``Six families ship``: 6)."""
    match = re.search(r'\b(\w+)\s+' + r'\s+'.join(phrase.split()), text)
    assert match, f'no count before {phrase!r}'
    return NUMBERS.index(match.group(1).lower())


def test_families_concept_describes_every_family():
    text = FAMILIES.read_text()
    names = _bullets(text, r'\*\*(\w+)\*\*')
    assert len(names) == len(set(names)), 'families.md: a family described twice'
    assert set(names) == set(models.BUILTIN), 'families.md: a bullet per family of BUILTIN'
    assert _count(text, 'families ship with the package') == len(models.BUILTIN), \
        'families.md: how many families ship'


def test_actuators_concept_describes_every_actuator():
    text = ACTUATORS.read_text()
    names = _bullets(text, r'`(\w+)`:')
    assert len(names) == len(set(names)), 'actuators.md: an actuator described twice'
    assert set(names) == set(actuators.BUILTIN), 'actuators.md: a bullet per actuator of BUILTIN'
    assert _count(text, 'ship with the package') == len(actuators.BUILTIN), \
        'actuators.md: how many actuators ship'


def test_effects_concept_lists_every_effect():
    text = EFFECTS.read_text()
    start = text.index('| effect | parameters |')
    names: list[str] = []
    for line in text[start:].split('\n')[2:]:
        if not line.startswith('|'):
            break
        for name in re.findall(r'`(\w+)`', line.strip('|').split('|')[0]):
            # `thrust_scale_port`, `_stbd`: a suffix replaces the previous name's last part
            names.append(names[-1].rsplit('_', 1)[0] + name if name.startswith('_') else name)
    assert len(names) == len(set(names)), 'effects.md: an effect listed twice'
    assert set(names) == set(effects.EFFECTS), 'effects.md: a row per effect of core/effects.py'
