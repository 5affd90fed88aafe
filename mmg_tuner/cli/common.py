"""Shared CLI plumbing: error reporting."""
from __future__ import annotations

import sys
from typing import Callable

from mmg_tuner.errors import MmgTunerError


def run_command(command: Callable[[list[str] | None], int], argv: list[str] | None) -> int:
    """Call command(argv); a MmgTunerError becomes 'ERROR: ...' and exit status 2."""
    try:
        return command(argv)
    except MmgTunerError as exc:
        print(f'ERROR: {exc}', file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print('interrupted', file=sys.stderr)
        return 130
