"""
Exceptions a user can act on.

Every message names the file, key, topic or time involved.
"""


class MmgTunerError(Exception):
    """Base class of every error this package raises on purpose."""


class ConfigError(MmgTunerError):
    """A ship config, parameter file or topic map is missing, malformed or out of range."""


class SimulationError(MmgTunerError):
    """A simulation left the model's range (u <= 0, rpm <= 0) or diverged (non-finite state)."""


class TrialDataError(MmgTunerError):
    """A recorded trial cannot be read or is unusable as it stands."""


class TuningError(MmgTunerError):
    """Tuning cannot start or continue (bad targets, bounds, checkpoint)."""


class DiagnosisError(MmgTunerError):
    """The diagnosis cannot run on the given trials."""


class OutputError(MmgTunerError):
    """An output location cannot be used (a file, not writable, in use, would overwrite)."""


class MissingDependencyError(MmgTunerError):
    """An optional dependency a feature needs is not installed (the message says how to)."""
