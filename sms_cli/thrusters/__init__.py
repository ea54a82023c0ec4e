"""Real thrusters (issue #12 item 1; Vicariotto 2023 §3.4.3, L534–L560): the mission's ``thrusters:``
section (``schema``), the set in the base frame and the cube preset (``layout``, ``build``), minimum-thrust
wrench allocation by HiGHS (``allocation``), on/off modulation with quantisation and MIB
(``modulation``), propellant drawn from the tank (``propellant``), the plant-side driver of the
simulation loop (``drive``), and the compile-time capability report and checks (``capability``,
``check``)."""
