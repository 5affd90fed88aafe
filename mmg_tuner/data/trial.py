"""
The trial type used everywhere downstream.

One type for recorded and simulated histories, defined in the core (``mmg_tuner.core.trial``) and
re-exported here.
"""
from __future__ import annotations

from mmg_tuner.core.layout import STATE_NAMES
from mmg_tuner.core.trial import Trial

__all__ = ['CSV_COLUMNS', 'STATE_COLUMNS', 'Trial']

STATE_COLUMNS = ('t',) + STATE_NAMES
CSV_COLUMNS = STATE_COLUMNS + ('rpm', 'rudder')
