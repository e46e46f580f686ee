"""The Gymnasium ids this package registers and the one function that registers them.

:mod:`plate_env` calls :func:`register` when it is imported; the benchmark's suites read :data:`FAITHFUL_IDS` from
here."""

from __future__ import annotations

from typing import Any

from plate_env.core.setup import MAX_PROBES_RANGE

#: The faithful ids (issue 33): the paper-faithful rigid tiles (``rigid_fast``) at the amplitudes its atlas
#: answers; ``PlateRotation-v1`` runs them live (evaluation), ``PlateRotationAtlas-v1`` answers from their 1 Hz atlas
#: (training, microseconds a probe). The same env contract as v0 (PlateRotationEnv's Version History).
FAITHFUL_IDS: dict[str, dict[str, Any]] = {
    "PlateRotation-v1": {"physics": "tilelink", "physics_options": {"model": "rigid_fast"},
                         "amplitudes_deg": (3.0, 6.0)},
    "PlateRotationAtlas-v1": {"physics": "atlas", "physics_options": {"model": "rigid_fast"},
                              "amplitudes_deg": (3.0, 6.0)},
}

#: Every registered id -> its ``gym.make`` keyword arguments (each also under the ``plate_env/`` namespace):
#: ``PlateRotationAtlas-v0`` is v0's training twin, the point mass's atlas (issue 41: an id alone must not train on
#: the live physics).
ENV_IDS: dict[str, dict[str, Any]] = {"PlateRotation-v0": {}, "PlateRotationAtlas-v0": {"physics": "atlas"},
                                      **FAITHFUL_IDS}


def register() -> None:
    """Register :data:`ENV_IDS` with gymnasium (idempotent). The env ends every episode itself (terminated: the
    agent stops, ``max_probes`` probes have run or ``max_sim_s`` is spent; never truncated), so the spec's
    ``max_episode_steps`` is the largest ``max_probes`` it accepts: a TimeLimit that bounds every episode and never
    cuts one short."""
    from gymnasium.envs.registration import register as gym_register
    from gymnasium.envs.registration import registry

    for name, kwargs in ENV_IDS.items():
        for env_id in (name, f"plate_env/{name}"):
            if env_id not in registry:
                gym_register(id=env_id, entry_point="plate_env.env:PlateRotationEnv",
                             vector_entry_point="plate_env.env.vector:PlateRotationVectorEnv",
                             max_episode_steps=MAX_PROBES_RANGE[1], kwargs=kwargs)
