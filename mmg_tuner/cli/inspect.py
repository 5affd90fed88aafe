"""
``inspect``: what a recording holds as a ship trial — like `ros2 bag info`.

Plus how it is read (the pose source: Odometry or NavSatFix + heading, the datum, frames, time
bases, topics found by type), a suspected command/state time offset, detected manoeuvres,
speed/rpm/rudder ranges and every problem found; ``--csv DIR`` writes each trial resampled in the
model frame. Exit status 1 when nothing usable is in the input.

Examples
--------
inspect trials/turning_p35 trials/zigzag_p20 --csv out/

"""  # noqa: A005  module name is the public command name (inspect), kept
from __future__ import annotations

import argparse
from dataclasses import replace
import sys

from mmg_tuner._outdir import OutputDir
from mmg_tuner.cli.args import add_reading_options, bounded
from mmg_tuner.cli.common import Parser, run_command
from mmg_tuner.data.consistency import refuse_warnings, warn_rpm_units, WarningLog
from mmg_tuner.data.csv_io import trial_csv_text
from mmg_tuner.data.load import parse_event_cut
from mmg_tuner.data.summary import format_summary, summarize_many
from mmg_tuner.data.topics import load_topic_map


DT = bounded(float, 1e-3, 3600.0, 'resampling step dt [s]')


def build_parser() -> argparse.ArgumentParser:
    ap = Parser(prog='inspect', description=__doc__.strip().split('\n')[0])
    ap.add_argument('inputs', nargs='+', help='rosbag2 dirs, .mcap, .csv, .dat, or folders')
    add_reading_options(ap, DT, 'resampling step [s] (default: topic map, 1.0)', scale=False)
    ap.add_argument('--ship', help='ship config name or YAML: samples beyond its plausible '
                                   'rpm, rudder and speed are dropped with a note (default: '
                                   'generic limits that fit any ship); astern propeller and '
                                   'u <= 0 are kept when its family covers them (lowspeed)')
    ap.add_argument('--csv', metavar='OUT_DIR',
                    help='write each trial as CSV into this new (or empty) folder')
    return ap


def command(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    tm = load_topic_map(args.topics)
    if args.dt is not None:
        tm = replace(tm, dt=args.dt)
    limits = ship = None
    keep_astern = False
    if args.ship:
        from mmg_tuner.core.limits import input_limits
        from mmg_tuner.core.ship import load_ship
        ship = load_ship(args.ship)
        limits = input_limits(ship)
        keep_astern = ship.family.astern_rpm and ship.family.astern_surge
    cut = parse_event_cut(args.cut_from_event) if args.cut_from_event else None
    out = OutputDir.open(args.csv, option='--csv') if args.csv else None
    try:
        with WarningLog() as log:
            summaries, trials = summarize_many(args.inputs, tm, limits, keep_astern, cut)
            if ship is not None:   # rpm logged as rev/s: the ship's own force balance says
                warn_rpm_units(trials, ship)
        if args.strict:
            refuse_warnings(log.lines)
        for rs in summaries:
            print(format_summary(rs))
        if out is not None:
            for tr in trials:
                path = out.write_text(f'{tr.name}.csv', trial_csv_text(tr))
                print(f'  wrote {path}')
    finally:
        if out is not None:
            out.close()
    print(f'{len(trials)} usable trial(s)')
    return 0 if trials else 1


def main(argv: list[str] | None = None) -> None:
    sys.exit(run_command(command, argv))


if __name__ == '__main__':
    main()
