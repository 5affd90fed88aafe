"""
mmg_tuner: learn, diagnose and serve a ship's 3-DOF MMG manoeuvring model.

Layers, each importing only those before it:
``core`` (model, integrators, manoeuvres; NumPy/numba only) -> ``data`` (trials in/out) ->
``tuning`` (CMA-ES) -> ``diagnosis`` -> ``api`` (the public Python API) -> ``cli``; ``ros``
(rclpy nodes) sits on top and is the only place that imports rclpy.

The public API (:mod:`mmg_tuner.api`), loaded on first use so that ``import mmg_tuner`` stays
light::

    import mmg_tuner as mt
    ship = mt.load_ship('suzaku')
    trials = mt.load_trials(['trials/'], ship=ship)
    fit = mt.tune(ship, trials[:4], test=trials[4:])
    dx = mt.diagnose(ship, trials[:4], test=trials[4:])
    run = mt.simulate(ship.with_params(dx.params), trials[5])
"""
from mmg_tuner.errors import (ConfigError, DiagnosisError, MmgTunerError, OutputError,
                              SimulationError, TrialDataError, TuningError)

_API = ('load_ship', 'load_model', 'Model', 'load_trials', 'tune', 'diagnose', 'simulate',
        'TuneConfig', 'TuneResult',
        'Fit', 'DiagnoseConfig', 'DiagnosisResult', 'ModelFit', 'Cause', 'BUDGETS',
        'evaluate', 'EvaluateConfig', 'EvaluateResult', 'identify', 'IdentifyConfig',
        'IdentifyResult')

__all__ = ['ConfigError', 'DiagnosisError', 'MmgTunerError', 'OutputError', 'SimulationError',
           'TrialDataError', 'TuningError', *_API]
__version__ = '0.1.0'


def __getattr__(name: str) -> object:
    # lazy (PEP 562): core modules import mmg_tuner.errors, which runs this file first
    if name in _API:
        from mmg_tuner import api
        return getattr(api, name)
    if name == 'fleet':  # the package, callable: mt.fleet(manifest, out, client=None)
        import importlib
        return importlib.import_module('mmg_tuner.fleet')
    raise AttributeError(f'module {__name__!r} has no attribute {name!r}')


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(_API))
