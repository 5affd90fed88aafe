"""
``precompile``: compile the simulator's kernels now, not on the first run.

Run once after ``colcon build`` (scripts/install.sh does): the first ``ros2 run mmg_tuner
sim_node`` or ``simulate`` then starts in seconds. Each kernel takes about 15 s on a 2-core
machine; already cached, about 0.1 s. The cache is per installation and per core source
(core/_numba_cache.py), so run it again after an upgrade.

Examples
--------
precompile

"""
from __future__ import annotations

import argparse
import sys

from mmg_tuner.cli.common import Parser, run_command


def build_parser() -> argparse.ArgumentParser:
    return Parser(prog='precompile', description=__doc__.strip().split('\n')[0])


def command(argv: list[str] | None = None) -> int:
    build_parser().parse_args(argv)
    from mmg_tuner.core._numba_cache import cache_dir
    from mmg_tuner.core.precompile import precompile
    print(f'compiling into {cache_dir()}', flush=True)
    precompile(lambda name, s: print(f'  {name}: {s:.1f} s', flush=True))
    return 0


def main(argv: list[str] | None = None) -> None:
    sys.exit(run_command(command, argv))


if __name__ == '__main__':
    main()
