"""
A new kind of vessel is new files only: no code above the vessel's own modules names one.

Outside ``core/models`` and ``core/actuators`` (where a family and an actuator declare
everything about themselves), no code line -- comments and docstrings aside -- may name the
twin-azimuth tug, its azimuths or the screw-and-rudder actuator, but the few listed below
with their reason. A command that needs something of an actuator asks its declarations
(``core/actuators/__init__.py``: channels, limits by unit, companions ``TRIALS``,
``SYMBOLIC``, ``IDENTIFY``, ``EFFECTS``, ``JOINTS``).
"""
import ast
import io
from pathlib import Path
import re
import tokenize

PACKAGE = Path(__file__).resolve().parents[2] / 'mmg_tuner'
NAMES = re.compile(r'tug|azimuth|twin|screw_rudder|qiuxin|otter', re.I)
ALLOWED = {
    # the library's own screw-and-rudder effects (rudder offset, steering-gear lag, rpm scale,
    # propeller side force): declared with the table, before the actuators' own, so that the
    # layout's parameter slots keep their order (saved models and checkpoints index them)
    'core/effects.py': 4,
    # the ship YAML's key steering.max_azimuth_deg, the limit of an angle command
    'core/limits.py': 4,
    # the parameters earlier versions read, refused naming what replaces them
    'ros/sim_node.py': 1,
}


def _code_lines(path: Path) -> list[int]:
    """Return the lines whose code (not a comment, not a docstring) names a vessel."""
    src = path.read_text()
    doc: set[int] = set()
    for node in ast.walk(ast.parse(src)):
        if isinstance(node, ast.Expr) and isinstance(node.value, ast.Constant) \
                and isinstance(node.value.value, str):
            doc.update(range(node.lineno, (node.end_lineno or node.lineno) + 1))
    lines = set()
    for tok in tokenize.generate_tokens(io.StringIO(src).readline):
        if tok.type in (tokenize.COMMENT, tokenize.NL, tokenize.NEWLINE) or tok.start[0] in doc:
            continue
        if NAMES.search(tok.string):
            lines.add(tok.start[0])
    return sorted(lines)


def test_no_code_above_the_vessel_modules_names_a_vessel():
    found = {}
    for path in sorted(PACKAGE.rglob('*.py')):
        rel = path.relative_to(PACKAGE).as_posix()
        if rel.startswith(('core/models/', 'core/actuators/')):
            continue
        lines = _code_lines(path)
        if len(lines) > ALLOWED.get(rel, 0):
            found[rel] = lines
    assert not found, ('code naming a vessel outside core/models and core/actuators (ask the '
                       f"actuator's declarations instead): {found}")


def test_the_check_sees_a_name_in_code_and_not_in_a_comment(tmp_path):
    p = tmp_path / 'm.py'
    p.write_text('"""A twin-azimuth tug."""\n# the tug\nx = 1\nname = "azimuth_port"\n')
    assert _code_lines(p) == [4]
