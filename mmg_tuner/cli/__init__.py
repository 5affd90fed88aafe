"""
Command-line tools.

Each ``command(...) -> int`` is the only place that catches

:class:`~mmg_tuner.errors.MmgTunerError` and prints ``ERROR: ...``; ``main`` wraps it.
"""
