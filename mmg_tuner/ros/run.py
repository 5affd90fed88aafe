"""
One way to run a node from a console script.

Declared, described parameters; errors a user can act on; a clean shutdown.
"""
from __future__ import annotations

from dataclasses import dataclass
import difflib
import faulthandler
import os
import signal
import sys
import threading
from types import FrameType
from typing import Any, Callable, Mapping, NoReturn

from mmg_tuner._limits import one_line
from mmg_tuner.errors import ConfigError, MmgTunerError
from rcl_interfaces.msg import FloatingPointRange, IntegerRange, ParameterDescriptor
import rclpy
from rclpy.exceptions import (InvalidParameterTypeException, InvalidParameterValueException,
                              ParameterException)
from rclpy.executors import ExternalShutdownException
from rclpy.impl.implementation_singleton import rclpy_implementation as _rclpy
from rclpy.node import Node


SHUTDOWN_TIMEOUT_S = 20.0  # destroying the node, shutting ROS down and leaving Python


@dataclass(frozen=True)
class Param:
    """
    A node parameter.

    Default, description (with units), optional inclusive range and whether it can change at run
    time (read_only: fixed once the node has started).
    """

    default: Any
    description: str
    range: tuple[float, float] | None = None  # noqa: A003
    read_only: bool = False
    constraints: str = ''

    def descriptor(self) -> ParameterDescriptor:
        d = ParameterDescriptor(description=self.description, read_only=self.read_only,
                                additional_constraints=self.constraints)
        if self.range is not None:
            lo, hi = self.range
            if isinstance(self.default, bool):
                pass
            elif isinstance(self.default, int):
                d.integer_range = [IntegerRange(from_value=int(lo), to_value=int(hi), step=0)]
            elif isinstance(self.default, float):
                d.floating_point_range = [FloatingPointRange(from_value=float(lo),
                                                             to_value=float(hi), step=0.0)]
        return d


def declare_parameters(node: Node, specs: Mapping[str, Param]) -> dict[str, Any]:
    """
    Declare every parameter with its descriptor.

    A value given at start that the descriptor refuses (type, range) becomes a one-line ConfigError
    naming it.
    """
    for name, spec in specs.items():
        try:
            node.declare_parameter(name, spec.default, spec.descriptor())
        except InvalidParameterTypeException:
            given = _override(node, name)
            kind = type(spec.default).__name__
            hint = f' (write {given}.0)' if isinstance(spec.default, float) and \
                isinstance(given, int) else ''
            raise ConfigError(f'parameter {name} := {given!r} has the wrong type: expected '
                              f'{kind}{hint}; {spec.description}') from None
        except InvalidParameterValueException:
            given = _override(node, name)
            lo, hi = spec.range if spec.range is not None else (None, None)
            raise ConfigError(f'parameter {name} := {given!r} is outside '
                              f'[{_fmt_bound(lo)}, {_fmt_bound(hi)}]; '
                              f'{spec.description}') from None
    for name in unknown_overrides(node):
        node.get_logger().warn(_unknown_message(node, name, specs))
    return {n: node.get_parameter(n).value for n in specs}


def unknown_overrides(node: Node) -> list[str]:
    """
    Name the -p / --params-file values no declared parameter takes.

    rclpy drops them without a word, so a typo (initial_sped) ran on the default.
    """
    return sorted(n for n in node._parameter_overrides
                  if not node.has_parameter(n) and not n.startswith('qos_overrides.'))


def _unknown_message(node: Node, name: str, specs: Mapping[str, Param]) -> str:
    close = difflib.get_close_matches(name, list(specs), n=1)
    hint = f'did you mean {close[0]}?' if close else 'ros2 param list shows the parameters'
    value = _override(node, name)
    return (f'parameter {name} := {value!r} is not a parameter of {node.get_name()} and is '
            f'ignored: {hint}')


def _fmt_bound(x: Any) -> str:   # x: a bound as the range holds it, an int or a float
    """Return a range bound as written: integers in full (2147483647, not 2.14748e+09)."""
    whole = isinstance(x, int) or (isinstance(x, float) and x.is_integer() and abs(x) < 1e15)
    return str(int(x)) if whole else f'{x:g}'


def _override(node: Node, name: str) -> Any:
    p = node._parameter_overrides.get(name)  # what -p / --params-file gave (rclpy keeps it)
    return p.value if p is not None else '?'


def spin_node(make_node: Callable[[], Node], args: list[str] | None = None) -> None:
    """
    Create and spin a node until shutdown.

    An MmgTunerError (bad ship, params or trial), a parameter the node refuses or ROS arguments rcl
    cannot parse are printed as one ``ERROR:`` line with exit code 2, a node's own SystemExit keeps
    its code, Ctrl-C and external shutdown end quietly.
    """
    # Ctrl-C raises KeyboardInterrupt wherever Python runs; inside rclpy's message conversion
    # that surfaces as a RuntimeError ("Unable to convert call argument") before the context is
    # shut down, so remember the interrupt to tell it from a real failure.
    interrupted = threading.Event()

    def on_sigint(signum: int, frame: FrameType | None) -> NoReturn:
        interrupted.set()
        raise KeyboardInterrupt

    signal.signal(signal.SIGINT, on_sigint)  # before rclpy.init, which chains to it
    try:
        rclpy.init(args=args)
    except _rclpy.RCLError as exc:
        print(f'ERROR: {_explain_init_error(exc, sys.argv if args is None else args)}',
              file=sys.stderr)
        sys.exit(2)
    try:
        node = make_node()
    except (MmgTunerError, ParameterException) as exc:
        # leave before the exception is released: freeing its traceback destroys the half-built
        # node, and that destructor (rcl/DDS teardown) hung a failed start in CI, past its one
        # ERROR line and before any watchdog could be armed
        _exit_now(2, f'ERROR: {one_line(str(exc))}')
    except SystemExit as exc:
        _exit_now(int(exc.code or 0))
    except (KeyboardInterrupt, ExternalShutdownException):
        _exit_now(0)
    code = 0
    try:
        rclpy.spin(node)
    except MmgTunerError as exc:   # one line of at most a screen (_limits.one_line)
        print(f'ERROR: {one_line(str(exc))}', file=sys.stderr)
        code = 2
    except ParameterException as exc:
        print(f'ERROR: {one_line(str(exc))}', file=sys.stderr)
        code = 2
    except SystemExit as exc:
        code = int(exc.code or 0)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except RuntimeError:  # rclpy taking a message while Ctrl-C shuts the context down
        # (rclpy imports ok from rclpy.utilities and exports it without an __all__)
        if rclpy.ok() and not interrupted.is_set():  # type: ignore[attr-defined]
            raise
    finally:
        # a shutdown that hangs must not keep the process: after SHUTDOWN_TIMEOUT_S print
        # every thread's stack and exit 1
        faulthandler.dump_traceback_later(SHUTDOWN_TIMEOUT_S, exit=True)
        node.destroy_node()
        if rclpy.ok():  # type: ignore[attr-defined]   # (as above)
            rclpy.shutdown()
    if code:
        # a failed start has nothing left to save: leave without the interpreter's finalization
        # (atexit handlers, thread joins), where faulthandler's watchdog no longer runs and a
        # start-up error was once seen to hang the process past its one ERROR line
        sys.stdout.flush()
        sys.stderr.flush()
        os._exit(code)
    sys.exit(code)


def _exit_now(code: int, message: str = '') -> None:
    """Print one line and leave at once: a failed start has nothing to save or tear down."""
    if message:
        print(message, file=sys.stderr)
    sys.stdout.flush()
    sys.stderr.flush()
    os._exit(code)


def _explain_init_error(exc: Exception, argv: list[str]) -> str:
    """
    Rcl refuses the command line (typically a --params-file it cannot parse).

    Say which file and, for a tuned params.yaml given by reflex, what to do instead.
    """
    files = [argv[i + 1] for i, a in enumerate(argv[:-1]) if a == '--params-file']
    for f in files:
        if _is_tuned_params(f):
            return (f'{f} is a tuned params.yaml from tune/diagnose (top-level "params:"), not '
                    'a ROS parameter file (<node>: ros__parameters: ...); load it with '
                    f'-p params_file:={f}')
    first = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
    if files:
        return (f'ROS could not read --params-file {" ".join(files)}: {first} (a ROS parameter '
                'file maps a node name to ros__parameters: see config/sim_node.yaml)')
    return f'ROS could not parse the command-line arguments: {first}'


def _is_tuned_params(path: str) -> bool:
    from mmg_tuner._limits import load_yaml
    try:
        doc = load_yaml(path, 'params file')   # size, depth and alias limits
    except ConfigError:
        return False
    return isinstance(doc, dict) and isinstance(doc.get('params'), dict) and \
        not any(isinstance(v, dict) and 'ros__parameters' in v for v in doc.values())
