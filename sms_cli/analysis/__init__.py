"""``sms analyze``: workspace sampling, kinematic indices (seed 004 §3.2), linear modal analysis.

Modules: ``schema`` (the mission's ``analysis:`` section), ``sampling`` (joint-space samples),
``indices`` (per-sample indices, batched), ``modal`` (linearised model, coupled modes),
``table`` / ``plots`` (artifacts), ``stage`` (``run_analysis``).
"""
