"""
The simulator's health as diagnostic_msgs/DiagnosticArray (for ``/diagnostics``).

Three statuses, each with key/values and a level (REP-107 style names "<node>: <part>"):

- ``real time``: requested and achieved real-time factor; WARN on a shortfall (< 90 %).
- ``commands``: each command's last value, age and state; WARN while a command is stale
  (older than command_stale_s, or never received in that long since the start:
  ``ros/command_watch.py``), timed out (command_timeout_s: zeroed) or for HOLD_S after a
  clamped one, ERROR for HOLD_S after one was rejected (ignored: the ship kept the previous
  value). A command the ship's model
  cannot take (thrusters on a family without them) is listed only once it arrives, as one
  WARN state "<name> unsupported" while such messages keep coming, with their count.
- ``model``: simulated time and divergence resets; ERROR for HOLD_S after a reset.

A condition is a *state*: the node logs its transitions once; the array says it at ~1 Hz.
"""
from __future__ import annotations

from dataclasses import dataclass, field
import math
from typing import Any, Mapping, Sequence, TYPE_CHECKING

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from mmg_tuner.ros.command_watch import channel_state

if TYPE_CHECKING:   # annotations only
    from mmg_tuner.core.plausibility import Finding

OK, WARN, ERROR = DiagnosticStatus.OK, DiagnosticStatus.WARN, DiagnosticStatus.ERROR
HOLD_S = 5.0  # [s, wall] a clamped/rejected command or a reset keeps its level this long
RTF_SHORTFALL = 0.9  # achieved / requested real-time factor below this is a WARN


@dataclass
class CommandHealth:
    """What the node knows about one command stream (times: steady wall clock [s])."""

    unit: str
    value: float
    required: bool = True   # wait_for_commands waits for it
    supported: bool = True  # False: the ship's model has no such input (every one refused)
    last_rx: float | None = None
    stale: bool = False
    timed_out: bool = False  # command_timeout_s passed: zeroed (thrust) until the next one
    clamped: int = 0
    rejected: int = 0
    last_clamped: float = -math.inf
    last_rejected: float = -math.inf
    last_problem: str = ''


@dataclass
class Health:
    """Counters and states behind the diagnostics; the node updates it, ``array`` reports."""

    node_name: str
    hardware_id: str
    commands: dict[str, CommandHealth] = field(default_factory=dict)
    resets: int = 0
    last_reset: float = -math.inf
    last_failure: str = ''
    rtf_requested: float = 1.0
    rtf_achieved: float | None = None
    waiting: bool = False
    since: float | None = None  # when the watch began (None: never received is not judged)

    def command(self, which: str, value: float | None, problem: str, now: float) -> None:
        """
        Record that a command arrived.

        Applied as ``value`` (None: rejected), with ``problem`` when it was clamped or rejected.
        """
        c = self.commands[which]
        c.last_rx = now
        c.timed_out = False
        if value is not None:
            c.value = value
        if problem:
            c.last_problem = problem
            if value is None:
                c.rejected += 1
                c.last_rejected = now
            else:
                c.clamped += 1
                c.last_clamped = now

    def ready(self) -> bool:
        """Every required command has arrived at least once."""
        return all(c.last_rx is not None for c in self.commands.values() if c.required)

    def update_stale(self, which: str, now: float, limit_s: float) -> str:
        """'stale' or 'resumed' on a transition of the command's staleness, else ''."""
        c = self.commands[which]
        stale = c.supported and channel_state(c.last_rx, now, self.since, limit_s,
                                              required=c.required).stale
        if stale == c.stale:
            return ''
        c.stale = stale
        return 'stale' if stale else 'resumed'

    def reset(self, failure: str, now: float) -> None:
        self.resets += 1
        self.last_reset = now
        self.last_failure = failure

    def array(self, now: float, stamp: Any, sim_time_s: float, limit_s: float) -> DiagnosticArray:
        msg = DiagnosticArray()
        msg.header.stamp = stamp
        msg.status = [self._real_time(), self._commands(now, limit_s),
                      self._model(now, sim_time_s)]
        return msg

    def _status(self, part: str, level: int, message: str, values: Mapping[str, object]
                ) -> DiagnosticStatus:
        return DiagnosticStatus(level=level, name=f'{self.node_name}: {part}', message=message,
                                hardware_id=self.hardware_id,
                                values=[KeyValue(key=k, value=str(v)) for k, v in values.items()])

    def _real_time(self) -> DiagnosticStatus:
        req, got = self.rtf_requested, self.rtf_achieved
        values = {'requested real-time factor': 'as fast as possible' if req == 0 else f'{req:g}',
                  'achieved real-time factor': '' if got is None else f'{got:.4g}'}
        if self.waiting:
            return self._status('real time', OK, 'waiting for both commands', values)
        if req > 0 and got is not None and got < RTF_SHORTFALL * req:
            return self._status('real time', WARN, f'real-time factor shortfall: {got:.3g} of '
                                f'{req:g}', values)
        return self._status('real time', OK, 'on time' if req > 0 else 'free running', values)

    def _commands(self, now: float, limit_s: float) -> DiagnosticStatus:
        values: dict[str, object]   # strings and counts
        level, problems, values = OK, [], {'stale after [s]': f'{limit_s:g}'}
        for which, c in self.commands.items():
            if not c.supported:
                if c.last_rx is not None:  # listed once someone sends it
                    values[f'{which} ignored (total)'] = c.rejected
                    values[f'{which} last problem'] = c.last_problem
                    if now - c.last_rx < HOLD_S:
                        level = max(level, WARN)
                        problems.append(f'{which} unsupported')
                continue
            age = 'never received' if c.last_rx is None else f'{now - c.last_rx:.1f}'
            values[f'{which} [{c.unit}]'] = f'{c.value:.6g}'
            values[f'{which} age [s]'] = age
            values[f'{which} stale'] = str(c.stale)
            if c.timed_out:
                values[f'{which} timed out'] = 'True'
            values[f'{which} clamped (total)'] = c.clamped
            values[f'{which} rejected (total)'] = c.rejected
            values[f'{which} last problem'] = c.last_problem
            if now - c.last_rejected < HOLD_S:
                level = max(level, ERROR)
                problems.append(f'{which} rejected')
            elif now - c.last_clamped < HOLD_S:
                level = max(level, WARN)
                problems.append(f'{which} clamped')
            if c.stale:
                level = max(level, WARN)
                problems.append(f'{which} ' + ('stale' if c.last_rx is not None
                                               else 'never received'))
            if c.timed_out:
                level = max(level, WARN)
                problems.append(f'{which} timed out')
        return self._status('commands', level, ', '.join(problems) or 'ok', values)

    def _model(self, now: float, sim_time_s: float) -> DiagnosticStatus:
        values = {'simulated time [s]': f'{sim_time_s:.3f}', 'divergence resets': self.resets,
                  'last failure': self.last_failure}
        if now - self.last_reset < HOLD_S:
            return self._status('model', ERROR, 'diverged: reset to the initial state', values)
        return self._status('model', OK, 'ok', values)


def plausibility_status(node_name: str, hardware_id: str, findings: Sequence[Finding]
                        ) -> DiagnosticStatus:
    """
    Return the ``model plausibility`` status of the simulated model (core/plausibility.py).

    OK when nothing is implausible; WARN listing each finding (a hull derivative's sign, a
    straight-line instability beyond its tolerance, a wrong-way turn) with its figure, ERROR
    for an impossible one (refused at load, so not met in a running node). ``findings``:
    :func:`mmg_tuner.core.plausibility.checked` of the node's ship, then
    :func:`mmg_tuner.learn.plausibility.network_checked` of its network (full rudder each way).
    """
    level = OK
    values = {}
    for f in findings:
        level = max(level, ERROR if f.level == 'error' else WARN)
        values[f.what] = f'{f.figure:.4g}: {f.text}'
    message = '; '.join(f'{f.what} {f.figure:.3g}' for f in findings) or 'plausible'
    return DiagnosticStatus(level=level, name=f'{node_name}: model plausibility',
                            message=message, hardware_id=hardware_id,
                            values=[KeyValue(key=k, value=str(v)) for k, v in values.items()])
