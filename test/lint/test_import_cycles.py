"""No import cycle anywhere in the package (deferred, in-function imports included)."""
import ast
from pathlib import Path

PKG = Path(__file__).resolve().parents[2] / 'mmg_tuner'


def _module(path: Path) -> str:
    parts = path.relative_to(PKG.parent).with_suffix('').parts
    return '.'.join(parts[:-1] if parts[-1] == '__init__' else parts)


def _import_nodes(tree):
    """Every import statement, in functions too, but not under ``if TYPE_CHECKING:``."""
    todo = [tree]
    while todo:
        node = todo.pop()
        if isinstance(node, ast.If) and getattr(node.test, 'id', '') == 'TYPE_CHECKING':
            todo.extend(node.orelse)
            continue
        if isinstance(node, (ast.Import, ast.ImportFrom)):
            yield node
        todo.extend(ast.iter_child_nodes(node))


def _graph() -> dict[str, set[str]]:
    mods = {_module(p): p for p in PKG.rglob('*.py')}
    graph: dict[str, set[str]] = {m: set() for m in mods}
    for m, path in mods.items():
        is_pkg = path.name == '__init__.py'
        for node in _import_nodes(ast.parse(path.read_text())):
            names = []
            if isinstance(node, ast.Import):
                names = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom):
                base = node.module or ''
                if node.level:
                    pkg = m.split('.') if is_pkg else m.split('.')[:-1]
                    base = '.'.join(pkg[:len(pkg) - node.level + 1] + ([base] if base else []))
                names = [base] + [f'{base}.{a.name}' for a in node.names]
            for n in names:
                if n in mods and n != m:
                    graph[m].add(n)
    return graph


def _cycles(graph):
    state, stack, found = {}, [], []

    def visit(m):
        state[m] = 1
        stack.append(m)
        for n in sorted(graph[m]):
            if state.get(n) == 1:
                found.append(stack[stack.index(n):] + [n])
            elif n not in state:
                visit(n)
        stack.pop()
        state[m] = 2
    for m in sorted(graph):
        if m not in state:
            visit(m)
    return found


def test_the_checker_finds_a_cycle():
    assert _cycles({'a': {'b'}, 'b': {'c'}, 'c': {'a'}}) == [['a', 'b', 'c', 'a']]
    assert _cycles({'a': {'b'}, 'b': set()}) == []


def test_no_import_cycle_in_the_package():
    graph = _graph()
    assert 'mmg_tuner.core.dynamics' in graph['mmg_tuner.core.integrate']
    cycles = [c for c in _cycles(graph)
              # a package importing its own submodules in __init__ is how packages work
              if not any(c[i + 1].startswith(c[i] + '.') for i in range(len(c) - 1))]
    assert not cycles, '\n'.join(' -> '.join(c) for c in cycles)
