"""The package ships its inline annotations to its users' type checkers (PEP 561)."""
from pathlib import Path

import mmg_tuner


def test_the_imported_package_carries_py_typed():
    # the package as imported (the colcon install in CI, else the source tree) has the marker
    assert (Path(mmg_tuner.__file__).parent / 'py.typed').is_file()
