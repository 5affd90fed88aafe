"""One way to run a node from a console script: errors a user can act on, a clean shutdown."""
from __future__ import annotations

import sys
from typing import Callable

import rclpy
from rclpy.executors import ExternalShutdownException
from rclpy.node import Node

from mmg_tuner.errors import MmgTunerError


def spin_node(make_node: Callable[[], Node], args=None) -> None:
    """Create and spin a node until shutdown; an MmgTunerError (bad ship, params or trial) is
    printed as one ``ERROR:`` line with exit code 2, a node's own SystemExit keeps its code,
    Ctrl-C and external shutdown end quietly."""
    rclpy.init(args=args)
    node = None
    code = 0
    try:
        node = make_node()
        rclpy.spin(node)
    except MmgTunerError as exc:
        print(f'ERROR: {exc}', file=sys.stderr)
        code = 2
    except SystemExit as exc:
        code = int(exc.code or 0)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        if node is not None:
            node.destroy_node()
        if rclpy.ok():
            rclpy.shutdown()
    sys.exit(code)
