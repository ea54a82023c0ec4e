"""Orbital ΔV, propellant and burn-time budgets (``sms budget``).

Modules: ``constants`` (μ, R, g0, J2), ``orbits`` (apsis-defined Keplerian orbits, vis-viva),
``maneuvers`` (impulsive and low-thrust manoeuvres), ``propulsion`` (rocket equation, burn
durations), ``budget`` (sequence evaluation, mass events, wet-mass sizing), ``schema`` (the
``budget:`` section of mission files), ``stage`` (results.json, CSV, plots, printed table).
SI units inside: metres, seconds, kilograms, radians.
"""
