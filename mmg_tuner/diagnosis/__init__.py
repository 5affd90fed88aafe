"""Diagnosis: what the tuned model gets wrong, which physical effect explains it, and the
held-out gain of the extended model. Imports core, data and tuning; never rclpy."""
from mmg_tuner.diagnosis.select import Diagnosis, DiagnosisSettings, diagnose

__all__ = ['Diagnosis', 'DiagnosisSettings', 'diagnose']
