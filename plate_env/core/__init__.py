"""Layer 0, the core: what the rest of the package talks about, in SI units, with no physics in it.

Objects (:mod:`~plate_env.core.objects`), the plate's motion (:mod:`~plate_env.core.motion`), what a probe is and
returns (:mod:`~plate_env.core.probe`) and a table of probes (:mod:`~plate_env.core.probe_table`), unit conversions
at the edges (:mod:`~plate_env.core.units`) and checks of user-given values (:mod:`~plate_env.core.checks`).

Layers, each importing only the ones below it (tests/test_code_health.py checks it): core -> surrogate -> physics
-> identify -> run -> env -> (plate_env_agents) -> bench -> build -> the edge (cli, plotting, the package's
``__init__``).
"""
