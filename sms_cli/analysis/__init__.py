"""``sms analyze``: workspace sampling, kinematic indices (Kraiem 2022 §3.2), linear modal analysis.

Modules: ``schema`` (the mission's ``analysis:`` section), ``sampling`` (joint-space samples),
``indices`` (per-sample indices, batched), ``modal`` (linearised model, coupled modes),
``table`` / ``plots`` (artifacts), ``stage`` (``run_analysis``).
"""
