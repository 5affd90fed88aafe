"""
The public Python API.

Everything ``tune`` and ``diagnose`` do, with typed results, for a notebook or another package. The
commands are thin wrappers: argparse -> a config dataclass -> one call here ->
``result.write(out)``.

Examples
--------
>>> import mmg_tuner as mt
>>> ship = mt.load_ship('suzaku')
>>> trials = mt.load_trials(['trials/'], ship=ship)
>>> fit = mt.tune(ship, trials[:4], test=trials[4:], max_evals=5000)
>>> fit.J.test, fit.bounds_hit
>>> dx = mt.diagnose(ship, trials[:4], test=trials[4:], budget='quick')
>>> [c.summary for c in dx.causes]
>>> run = mt.simulate(ship.with_params(dx.params), trials[5])

Progress and messages go to the ``mmg_tuner`` loggers (silence them with
``logging.getLogger('mmg_tuner').setLevel(logging.WARNING)``). Errors are
:class:`~mmg_tuner.errors.MmgTunerError` subclasses naming the option and value.

One module per workflow: :mod:`~mmg_tuner.api.loading` (ships, models, trials),
:mod:`~mmg_tuner.api.tuning` (``tune``, its optional residual network),
:mod:`~mmg_tuner.api.diagnosing`, :mod:`~mmg_tuner.api.evaluating` (``simulate``, ``evaluate``),
:mod:`~mmg_tuner.api.identifying` (control-oriented models, local -> global); the names below
are the public surface.

"""
from mmg_tuner.api._common import config_fields
from mmg_tuner.api.diagnosing import (diagnose, DiagnoseConfig, DiagnosisResult, ModelFit,
                                      split_alternate)
from mmg_tuner.api.evaluating import evaluate, EvaluateConfig, simulate
from mmg_tuner.api.identifying import identify, IdentifyConfig
from mmg_tuner.api.loading import load_model, load_ship, load_trials
from mmg_tuner.api.tuning import (Fit, INDEX_WEIGHTS, MODEL_CHOICES, RESIDUAL_FILE,
                                  RESIDUAL_KINDS, tune, TuneConfig, TuneResult)
# the results and names the workflows return or take, from where they are defined
from mmg_tuner.core.effects import EFFECTS
from mmg_tuner.data.trial import Trial
from mmg_tuner.diagnosis.results import Cause
from mmg_tuner.diagnosis.settings import BUDGETS
from mmg_tuner.learn.model import Model
from mmg_tuner.tuning.evaluate import EvaluateResult
from mmg_tuner.tuning.lo_go import IdentifyResult

__all__ = ['BUDGETS', 'Cause', 'DiagnoseConfig', 'DiagnosisResult', 'Fit', 'ModelFit',
           'Model', 'TuneConfig', 'TuneResult', 'diagnose', 'load_model', 'load_ship',
           'load_trials', 'simulate',
           'tune', 'EvaluateConfig', 'EvaluateResult', 'evaluate', 'IdentifyConfig',
           'IdentifyResult', 'identify', 'split_alternate', 'config_fields', 'Trial', 'EFFECTS',
           'INDEX_WEIGHTS', 'MODEL_CHOICES', 'RESIDUAL_FILE', 'RESIDUAL_KINDS']
