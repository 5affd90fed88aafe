"""
One sample loop: every whole run of the package is ``core.integrate.drive``.

The one step function ``integrate.advance`` is called by the one sample loop (``drive``) and by
the node's stepper (``stepper._advance_checked``: the same step under its checks, one call per
tick), nowhere else; a new way to run a trial is a mode of ``drive``, not a loop of its own.
Read from the source with ``ast``: calls of the name, or of ``integrate.<name>`` (a sensor
channel's own ``.advance()`` in ``ros/`` is another function).
"""
import ast
from pathlib import Path

PACKAGE = Path(__file__).resolve().parents[2] / 'mmg_tuner'
ALLOWED = {('core/integrate.py', 'drive'), ('core/stepper.py', '_advance_checked')}


def _callers(name: str) -> set[tuple[str, str]]:
    """Return (module path, enclosing function) of every call of ``name`` in the package."""
    out = set()
    for path in PACKAGE.rglob('*.py'):
        tree = ast.parse(path.read_text(), str(path))
        for fn in ast.walk(tree):
            if not isinstance(fn, (ast.FunctionDef, ast.AsyncFunctionDef)):
                continue
            for node in ast.walk(fn):
                if isinstance(node, ast.Call):
                    f = node.func
                    called = f.id if isinstance(f, ast.Name) else \
                        f.attr if (isinstance(f, ast.Attribute) and isinstance(f.value, ast.Name)
                                   and f.value.id == 'integrate') else ''
                    if called == name:
                        out.add((path.relative_to(PACKAGE).as_posix(), fn.name))
    return out


def test_advance_is_stepped_by_the_one_sample_loop_and_the_node_alone():
    assert _callers('advance') == ALLOWED


def test_every_whole_run_kernel_goes_through_drive():
    drivers = {fn for _, fn in _callers('drive')}
    assert {'_simulate_one', '_run_maneuver', '_trajectory_cost', '_trajectory_residuals',
            'simulate_hybrid_one', 'steer_hybrid_one'} <= drivers, drivers
