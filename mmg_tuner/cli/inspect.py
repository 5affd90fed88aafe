"""``inspect``: what a recording holds as a ship trial — like `ros2 bag info`, plus detected
manoeuvres, speed/rpm/rudder ranges and every problem found; ``--csv DIR`` writes each trial
resampled in the model frame. Exit status 1 when nothing usable is in the input.

Example:
    inspect trials/turning_p35 trials/zigzag_p20 --csv out/
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

from mmg_tuner.cli.common import run_command
from mmg_tuner.data.csv_io import write_trial_csv
from mmg_tuner.data.summary import format_summary, summarize
from mmg_tuner.data.topics import load_topic_map


def build_parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(prog='inspect', description=__doc__.split('\n')[0],
                                 formatter_class=argparse.ArgumentDefaultsHelpFormatter)
    ap.add_argument('inputs', nargs='+', help='rosbag2 dirs, .mcap, .csv, .dat, or folders')
    ap.add_argument('--topics', help='topic map YAML (default: conventions.md topics)')
    ap.add_argument('--dt', type=float, help='resampling step [s] (default: topic map, 1.0)')
    ap.add_argument('--csv', metavar='OUT_DIR', help='write each trial as CSV here')
    return ap


def command(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    tm = load_topic_map(args.topics)
    if args.dt:
        from dataclasses import replace
        tm = replace(tm, dt=args.dt)
    usable = 0
    for inp in args.inputs:
        if not Path(inp).exists():
            print(f'{inp}\n  PROBLEM: no such file or directory')
            continue
        summaries, trials = summarize(inp, tm)
        for rs in summaries:
            print(format_summary(rs))
        usable += len(trials)
        if args.csv:
            for tr in trials:
                out = Path(args.csv) / f'{tr.name}.csv'
                write_trial_csv(tr, out)
                print(f'  wrote {out}')
    print(f'{usable} usable trial(s)')
    return 0 if usable else 1


def main(argv: list[str] | None = None) -> None:
    sys.exit(run_command(command, argv))


if __name__ == '__main__':
    main()
