"""
The ROS tests' shared harness: a private graph and node processes whose output is kept.

Used by test_ros_nodes, test_ros_system and test_round_trip (which import rclpy first and are
skipped without it). A node's output is read as it goes by a thread: an assertion inside a
test can show what the node has said so far, and a chatty node never blocks on a full pipe.
"""
import contextlib
import os
import random
import signal
import subprocess
import sys
import threading
import time

from conftest import installed_executable


def ros_graph(tmp_path_factory, driver: str, domains: tuple[int, int], seed: int):
    """
    Yield (env, node, executor) on a private ROS graph; shut down afterwards.

    Random domain in ``domains`` (seeded by the pid + seed, so concurrent runs differ),
    localhost only, logs in a temp dir.
    """
    import rclpy
    from rclpy.executors import SingleThreadedExecutor
    env = {'ROS_DOMAIN_ID': str(random.Random(os.getpid() + seed).randint(*domains)),
           'ROS_AUTOMATIC_DISCOVERY_RANGE': 'LOCALHOST',
           'ROS_LOG_DIR': str(tmp_path_factory.mktemp('roslog'))}
    saved = {k: os.environ.get(k) for k in env}
    os.environ.update(env)
    ctx = rclpy.context.Context()
    rclpy.init(context=ctx)
    node = rclpy.create_node(driver, context=ctx)
    ex = SingleThreadedExecutor(context=ctx)
    ex.add_node(node)
    try:
        yield dict(os.environ), node, ex
    finally:
        node.destroy_node()
        rclpy.shutdown(context=ctx)
        for k, v in saved.items():
            if v is None:
                os.environ.pop(k, None)
            else:
                os.environ[k] = v


class NodeProcess(subprocess.Popen):
    """A node's process; ``output`` is what it has printed so far (stdout and stderr)."""

    def __init__(self, cmd: list[str], env: dict) -> None:
        super().__init__(cmd, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                         text=True)
        self.lines: list[str] = []
        self.reader = threading.Thread(target=self._read, daemon=True)
        self.reader.start()

    def _read(self) -> None:
        for line in self.stdout:
            self.lines.append(line)

    @property
    def output(self) -> str:
        return ''.join(self.lines)


def start(exe: str, env: dict, *params: str, ros_args: tuple = ()) -> NodeProcess:
    """Start an installed node (as ``ros2 run`` would), else its module, with ``-p`` params."""
    path = installed_executable(exe)
    cmd = [path] if path else [sys.executable, '-m', f'mmg_tuner.ros.{exe}']
    return NodeProcess(cmd + ['--ros-args', *ros_args] + [a for p in params for a in ('-p', p)],
                       env)


def stop(proc: NodeProcess) -> str:
    """Stop the node (SIGINT, then SIGKILL after 10 s) and return all it printed."""
    if proc.poll() is None:
        proc.send_signal(signal.SIGINT)
    try:
        proc.wait(timeout=10)
    except subprocess.TimeoutExpired:
        proc.kill()
        proc.wait()
    proc.reader.join(timeout=10)
    return proc.output


@contextlib.contextmanager
def running(exe: str, env: dict, *ros_args: str, params: tuple = ()):
    """Run a node for the duration of the block; always stopped afterwards (see stop)."""
    proc = start(exe, env, *params, ros_args=ros_args)
    try:
        yield proc
    finally:
        stop(proc)


def spin_until(ex, cond, timeout=30.0, every=None) -> bool:
    """Spin until cond() or timeout [s]; call every() before each spin; return cond()."""
    t_end = time.monotonic() + timeout
    while time.monotonic() < t_end and not cond():
        if every is not None:
            every()
        ex.spin_once(timeout_sec=0.05)
    return cond()
