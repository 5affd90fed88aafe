"""
Whether sim_node is being driven: one command channel's state from the age of its last message.

Pure (no ROS, no clock of its own): the node asks once a second (``ros/health.py`` keeps the
states, ``ros/sim_node.py`` logs their transitions and zeroes thrust on a timeout), and the
tests ask without ROS (test/data/test_units_and_spikes.py).

- *stale*: the last message is older than ``stale_s``, or none has come in the ``stale_s``
  since the watch began (a wrong topic name, a driver not started): a diagnostics WARN. An
  optional channel (a screw-and-rudder ship's bow and stern thrusters) that never received a
  message is not stale: a ship driven by rudder and rpm alone is driven.
- *timed out*: the same age beyond ``timeout_s`` (0: never): the node zeroes the thrust and
  rpm channels (:func:`zeroed_on_timeout`) and holds the rudder and azimuth angles.
"""
from __future__ import annotations

from dataclasses import dataclass
import math


@dataclass(frozen=True)
class ChannelState:
    """One channel at one time: age [s] since its last message (since the watch began if none)."""

    age_s: float
    received: bool
    stale: bool
    timed_out: bool


def channel_state(last_rx: float | None, now: float, since: float | None, stale_s: float,
                  timeout_s: float = 0.0, required: bool = True) -> ChannelState:
    """
    Return the channel's state at ``now`` (times in seconds on one steady clock).

    last_rx: when its last message arrived (None: never); since: when the watch began (the
    node's start; None: a channel that never received is judged neither stale nor timed out);
    stale_s: the age beyond which it is stale; timeout_s: the age beyond which its thrust is
    zeroed (0: off); required: False for an optional channel (never received is then fine).
    """
    if last_rx is None:
        if since is None or not required:
            return ChannelState(math.inf, False, False, False)
        age = now - since
    else:
        age = now - last_rx
    return ChannelState(age, last_rx is not None, age > stale_s,
                        timeout_s > 0 and age > timeout_s)


def zeroed_on_timeout(channel: str) -> bool:
    """Whether a timed-out channel is set to zero: shaft speeds and rpm yes, angles held."""
    return channel == 'rpm' or channel.endswith('_thruster') or channel.startswith('n_')
