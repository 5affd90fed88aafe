"""
Diagnosis: what the tuned model gets wrong.

Which physical effect explains it, and the held-out gain of the extended model. Imports core, data
and tuning; never rclpy.

``select`` holds the search (:func:`diagnose`); ``settings`` its settings
(:class:`DiagnosisSettings`, budgets); ``stats`` the one acceptance rule (:func:`acceptance`)
used by its forward and backward steps, and the jackknife; ``results`` the typed results
(:class:`Cause`, :class:`Diagnosis`); ``checkpoint`` the stored tunings; ``context`` says
which effects are physically possible where the trials were recorded (:class:`Setting`);
``lsq`` the warm-started local re-tunes; ``advice`` the trial that would settle what the
trials cannot (:class:`TrialSpec`); ``residuals`` and ``report`` describe what remains.
"""
from mmg_tuner.diagnosis.advice import TrialSpec
from mmg_tuner.diagnosis.context import Setting
from mmg_tuner.diagnosis.results import Cause, Diagnosis
from mmg_tuner.diagnosis.select import diagnose
from mmg_tuner.diagnosis.settings import BUDGETS, DiagnosisSettings
from mmg_tuner.diagnosis.stats import acceptance, Verdict

__all__ = ['BUDGETS', 'Cause', 'Diagnosis', 'DiagnosisSettings', 'Setting', 'TrialSpec',
           'Verdict', 'acceptance', 'diagnose']
