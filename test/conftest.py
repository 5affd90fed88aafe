"""
Shared fixtures.

Tests run from a colcon install or a source checkout alike.
"""
from mmg_tuner.core.ship import load_ship
import pytest


@pytest.fixture(scope='session')
def suzaku():
    return load_ship('suzaku')


@pytest.fixture(scope='session')
def kvlcc2():
    return load_ship('kvlcc2')


def installed_executable(name: str):
    """
    Return the path of an installed executable as `ros2 run` finds it, or None.

    Path of an installed executable as `ros2 run mmg_tuner <name>` finds it
    (<prefix>/lib/mmg_tuner/<name>), or None when the package is not installed.
    """
    import os
    from pathlib import Path
    prefixes = [p for v in ('AMENT_PREFIX_PATH', 'COLCON_PREFIX_PATH')
                for p in os.environ.get(v, '').split(os.pathsep) if p]
    for prefix in prefixes:
        for cand in (Path(prefix) / 'lib' / 'mmg_tuner' / name,
                     Path(prefix) / 'mmg_tuner' / 'lib' / 'mmg_tuner' / name):
            if cand.is_file() and os.access(cand, os.X_OK):
                return str(cand)
    return None
