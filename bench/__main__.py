"""
Command line of the benchmark suite: ``python -m bench list`` and ``python -m bench run NAME``.

Run from the repository root (the package is imported from the checkout).
"""
from __future__ import annotations

import argparse
from pathlib import Path
import shlex
import sys

from bench import benchmarks, RESULTS_DIR, run_benchmark


def build_parser() -> argparse.ArgumentParser:
    """Return the parser of ``python -m bench``."""
    ap = argparse.ArgumentParser(prog='python -m bench', allow_abbrev=False,
                                 description='The mmg_tuner benchmark suite.')
    sub = ap.add_subparsers(dest='action', required=True)
    sub.add_parser('list', help='print each benchmark with a one-line description')
    run = sub.add_parser('run', allow_abbrev=False,
                         help='run one benchmark and write bench/results/NAME.json; '
                         'arguments it does not know are passed on to the benchmark')
    run.add_argument('name', help='a benchmark (python -m bench list)')
    run.add_argument('--quick', action='store_true',
                     help='a small budget: well under a minute where the benchmark allows')
    run.add_argument('--results-dir', type=Path, default=RESULTS_DIR,
                     help='write NAME.json here (default: bench/results)')
    return ap


def main(argv: list[str] | None = None) -> int:
    """Run the command; return the exit code."""
    argv = sys.argv[1:] if argv is None else argv
    args, rest = build_parser().parse_known_args(argv)
    known = benchmarks()
    if args.action == 'list':
        if rest:
            build_parser().error(f'unrecognized arguments: {" ".join(rest)}')
        width = max(map(len, known))
        for b in known.values():
            print(f'{b.name:{width}s}  {b.description}')
        return 0
    if args.name not in known:
        print(f'ERROR: no benchmark {args.name!r}; python -m bench list gives: '
              f'{", ".join(known)}', file=sys.stderr)
        return 2
    command = shlex.join(['python', '-m', 'bench', *argv])
    path = run_benchmark(args.name, args.quick, rest, args.results_dir, command)
    print(f'figures: {path}')
    return 0


if __name__ == '__main__':
    sys.exit(main())
