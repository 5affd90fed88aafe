"""
Measure the simulator node's speed.

CPU share of sim_node publishing at 50 Hz in real time, and the free-running speed of the
stepper (SUZAKU, dt = 0.1 s; Esso Osaka astern with thrusters) and of the node. Targets:
< 5 % of one core at 50 Hz; >= 1000x real time free-running.
    python -m bench run bench_node [--quick] [--window S]  (needs rclpy)

--quick measures the node's CPU share over 8 s instead of 20 s.
"""
from __future__ import annotations

import argparse
import math
import os
from pathlib import Path
import subprocess
import sys
import time

from mmg_tuner.core.ship import load_ship
from mmg_tuner.core.stepper import ShipSimulator


def cpu_seconds(pid: int) -> float:
    fields = Path(f'/proc/{pid}/stat').read_text().rsplit(')', 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf('SC_CLK_TCK')


def benchmark(quick: bool, argv: list[str]) -> dict:
    """Entry point of ``python -m bench run bench_node`` (``--quick``: an 8 s CPU window)."""
    return main((['--window', '8'] if quick else []) + argv)


def main(argv: list[str] | None = None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.strip().split('\n')[0])
    ap.add_argument('--window', type=float, default=20.0,
                    help='measure the CPU share over this many seconds')
    args = ap.parse_args(argv)
    figures = {}
    sim = ShipSimulator(load_ship('suzaku'), dt=0.1, x0=[0, 0, 0, 3.0, 0, 0], rpm=106.0)
    sim.set_rudder(math.radians(20))
    n = 200_000
    t0 = time.perf_counter()
    sim.step(n)
    wall = time.perf_counter() - t0
    print(f'free-running stepper: {n / wall:,.0f} steps/s = {n * 0.1 / wall:,.0f}x real time '
          '(SUZAKU, RK4, dt 0.1 s)')
    figures['stepper_suzaku_real_time_factor'] = n * 0.1 / wall
    # the lowspeed family astern with both thrusters (issue 12): 3 m model, so dt 0.05 s
    sim = ShipSimulator(load_ship('esso_osaka_3m'), dt=0.05, x0=[0, 0, 0, 0.0, 0, 0], rpm=0.0)
    sim.set_rpm(-300.0)
    sim.set_thruster('bow', 10.0)
    sim.set_thruster('stern', -10.0)
    t0 = time.perf_counter()
    sim.step(n)
    wall = time.perf_counter() - t0
    print(f'free-running stepper: {n / wall:,.0f} steps/s = {n * 0.05 / wall:,.0f}x real time '
          '(esso_osaka_3m astern with thrusters, RK4, dt 0.05 s)')
    figures['stepper_esso_astern_thrusters_real_time_factor'] = n * 0.05 / wall
    env = dict(os.environ, ROS_DOMAIN_ID='77', ROS_AUTOMATIC_DISCOVERY_RANGE='LOCALHOST',
               ROS_LOG_DIR='/tmp/mmg_bench_roslog', PYTHONPATH=str(Path(__file__).parents[1]))
    proc = subprocess.Popen([sys.executable, '-m', 'mmg_tuner.ros.sim_node', '--ros-args',
                             '-p', 'rate_hz:=50.0', '-p', 'dt:=0.1'], env=env,
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        time.sleep(8.0)  # start-up (imports, kernel load) is not the steady state
        c0, w0 = cpu_seconds(proc.pid), time.monotonic()
        time.sleep(args.window)
        c1, w1 = cpu_seconds(proc.pid), time.monotonic()
    finally:
        proc.terminate()
        proc.wait(10)
    print(f'sim_node at 50 Hz, real time: {100 * (c1 - c0) / (w1 - w0):.1f} % of one core '
          f'over {w1 - w0:.0f} s')
    figures['node_cpu_percent_of_one_core_at_50_Hz'] = 100 * (c1 - c0) / (w1 - w0)
    figures['node_free_running_real_time_factor'] = free_running_factor(env)
    print(f"sim_node free-running: {figures['node_free_running_real_time_factor']:,.0f}x real "
          'time (simulated seconds on its /clock per wall second)')
    return figures


def free_running_factor(env: dict, window_s: float = 10.0) -> float:
    import rclpy
    from rosgraph_msgs.msg import Clock as ClockMsg
    env = dict(env, ROS_DOMAIN_ID='78')
    os.environ.update({k: env[k] for k in ('ROS_DOMAIN_ID', 'ROS_AUTOMATIC_DISCOVERY_RANGE')})
    proc = subprocess.Popen([sys.executable, '-m', 'mmg_tuner.ros.sim_node', '--ros-args',
                             '-p', 'rate_hz:=50.0', '-p', 'dt:=0.1', '-p',
                             'real_time_factor:=0.0', '-p', 'publish_clock:=true'], env=env,
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    rclpy.init()
    node = rclpy.create_node('bench_clock')
    seen = []
    node.create_subscription(ClockMsg, '/clock', lambda m: seen.append(
        (time.monotonic(), m.clock.sec + m.clock.nanosec * 1e-9)), 10)
    try:
        t_end = time.monotonic() + 30.0
        while time.monotonic() < t_end and not seen:
            rclpy.spin_once(node, timeout_sec=0.1)
        t_end = time.monotonic() + window_s
        while time.monotonic() < t_end:
            rclpy.spin_once(node, timeout_sec=0.1)
    finally:
        proc.terminate()
        proc.wait(10)
        node.destroy_node()
        rclpy.shutdown()
    (w0, s0), (w1, s1) = seen[0], seen[-1]
    return (s1 - s0) / (w1 - w0)


if __name__ == '__main__':
    main()
