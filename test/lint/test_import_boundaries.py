"""Layers run one way: core -> data -> learn -> tuning -> diagnosis -> api -> cli; rclpy: ros/."""
import ast
from pathlib import Path

import pytest

PKG = Path(__file__).resolve().parents[2] / 'mmg_tuner'
ORDER = ['core', 'data', 'learn', 'tuning', 'diagnosis', 'api', 'fleet', 'cli']


def imports(path: Path) -> set[str]:
    tree = ast.parse(path.read_text())
    names = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            names.update(a.name for a in node.names)
        elif isinstance(node, ast.ImportFrom) and node.module:
            names.add(node.module)
    return names


@pytest.mark.parametrize('path', sorted(PKG.rglob('*.py')), ids=lambda p: str(p.relative_to(PKG)))
def test_layering(path):
    layer = path.relative_to(PKG).parts[0].removesuffix('.py')  # api/ is a layer
    mods = imports(path)
    if layer != 'ros':
        assert not any(m.split('.')[0] in ('rclpy', 'nav_msgs', 'std_msgs', 'geometry_msgs',
                                           'sensor_msgs', 'std_srvs') for m in mods), path
    if path.relative_to(PKG).parts[:2] not in (('learn', '_engine.py'), ('learn', 'train.py')):
        assert not any(m.split('.')[0] in ('jax', 'jaxlib', 'equinox', 'optax')
                       for m in mods), f'{path} imports JAX (allowed in learn only)'
    if layer in ORDER:
        allowed = ORDER[:ORDER.index(layer) + 1]
        for m in mods:
            parts = m.split('.')
            if parts[0] == 'mmg_tuner' and len(parts) > 1 and parts[1] in ORDER + ['ros']:
                assert parts[1] in allowed, f'{path}: {layer} imports {m}'
