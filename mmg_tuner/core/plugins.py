"""
Families and actuators from outside the package: the plugin lists.

A package (or a test) adds a model family or an actuator model without editing ``core``:
name its module, fully qualified, in an entry point of the group ``mmg_tuner.families`` or
``mmg_tuner.actuators`` (``pyproject``/``setup.cfg``: ``toy = mypkg.toy_family``), or in the
environment variables ``MMG_TUNER_FAMILIES`` / ``MMG_TUNER_ACTUATORS`` (comma-separated
module names). Both are read once, when ``mmg_tuner`` is first imported: the parameter layout
and the compiled kernels are fixed from then on. The registered name is the module's last
component (``mypkg.toy_family`` -> ``toy_family``).
"""
from __future__ import annotations

from importlib import metadata
import os

_GROUPS = {'families': ('mmg_tuner.families', 'MMG_TUNER_FAMILIES'),
           'actuators': ('mmg_tuner.actuators', 'MMG_TUNER_ACTUATORS')}


def modules(kind: str) -> tuple[str, ...]:
    """Fully qualified module names of the plugin ``kind`` ('families' or 'actuators')."""
    group, env = _GROUPS[kind]
    names = [ep.value.split(':')[0] for ep in metadata.entry_points(group=group)]
    names += [m.strip() for m in os.environ.get(env, '').split(',') if m.strip()]
    return tuple(dict.fromkeys(names))
