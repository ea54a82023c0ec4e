"""Hardware-in-the-loop export (``sms export hil``, Vicariotto 2023 §6.2): a two-spacecraft run's relative
motion as commands to the robots of a HIL facility.

Modules, one job each: ``schema`` (the facility file), ``motion`` (reading the run), ``poses`` (the (6.2)
mapping and its twist), ``reach`` (inverse-kinematics reachability), ``workspace`` (absolute vs relative
envelope metrics), ``export`` (CSV and MCAP writers), ``plots`` (workspace.png), ``stage`` (the command).
"""
