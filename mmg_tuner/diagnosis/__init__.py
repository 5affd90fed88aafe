"""
Diagnosis: what the tuned model gets wrong.

Which physical effect explains it, and the held-out gain of the extended model. Imports core, data
and tuning; never rclpy.

``select`` holds the search (:func:`diagnose`), the one acceptance rule (:func:`acceptance`)
used by its forward and backward steps, and the typed results (:class:`Cause`,
:class:`Diagnosis`); ``context`` says which effects are physically possible where the trials
were recorded (:class:`Setting`); ``lsq`` the warm-started local re-tunes; ``advice`` the
trial that would settle what the trials cannot (:class:`TrialSpec`); ``residuals`` and
``report`` describe what remains.
"""
from mmg_tuner.diagnosis.advice import TrialSpec
from mmg_tuner.diagnosis.context import Setting
from mmg_tuner.diagnosis.select import (acceptance, BUDGETS, Cause, diagnose, Diagnosis,
                                        DiagnosisSettings, Verdict)

__all__ = ['BUDGETS', 'Cause', 'Diagnosis', 'DiagnosisSettings', 'Setting', 'TrialSpec',
           'Verdict', 'acceptance', 'diagnose']
