"""
What the family and actuator registries share: names -> modules, and literal declarations.

A registered model (family or actuator) is a module: a built-in one in its package
(``core/models``, ``core/actuators``), or a plugin named by its full module path
(``core/plugins.py``). The parameter layout must be known before any kernel is compiled, so
``PARAMS`` is read from the module's source as a literal, without importing it.
"""
from __future__ import annotations

import ast
import importlib.util
from pathlib import Path
from typing import Any

from mmg_tuner.core import plugins


def module_name(package: str, name: str, plugins: dict[str, str]) -> str:
    """Return the importable module of registry entry ``name`` (built-in or plugin)."""
    return plugins.get(name, f'{package}.{name}')


def source_path(module: str) -> Path:
    """Return the source file of ``module`` without importing it (ImportError if none)."""
    spec = importlib.util.find_spec(module)
    if spec is None or not spec.origin or not spec.origin.endswith('.py'):
        raise ImportError(f'cannot find the source of module {module!r}')
    return Path(spec.origin)


def declared(module: str, key: str, default: Any = None) -> Any:
    """Return the literal ``key = ...`` at the top level of ``module``'s source."""
    path = source_path(module)
    for node in ast.parse(path.read_text()).body:
        if (isinstance(node, ast.Assign) and len(node.targets) == 1
                and getattr(node.targets[0], 'id', None) == key):
            return ast.literal_eval(node.value)
    if default is not None:
        return default
    raise ImportError(f'{path}: no literal {key} = (...) at module level')


def plugin_map(modules: tuple[str, ...], builtin: tuple[str, ...], what: str) -> dict[str, str]:
    """Registry name -> module of each plugin; a name clash with a built-in is an error."""
    out: dict[str, str] = {}
    for mod in modules:
        name = mod.rsplit('.', 1)[-1]
        if name in builtin or name in out:
            raise ImportError(f'plugin {what} {mod!r}: the name {name!r} is already taken')
        out[name] = mod
    return out


def registry(builtin: tuple[str, ...], group: str,
             what: str) -> tuple[dict[str, str], tuple[str, ...]]:
    """
    Return (name -> module of each plugin in ``group``, the registered names).

    The names are the built-ins, then the plugins: a built-in keeps its position (a family's
    code) whatever is installed beside it.
    """
    plugins_of = plugin_map(plugins.modules(group), builtin, what)
    return plugins_of, builtin + tuple(plugins_of)
