"""rl-zoo3's view of the hyperparameters installed with this package: ``--conf-file plate_env_agents.zoo`` (rl-zoo3
imports a ``--conf-file`` that is not a ``.yml``/``.py`` path as a module and reads its ``hyperparams``)::

    python -m rl_zoo3.train --algo sac --env PlateRotationAtlas-v0 --gym-packages plate_env \
        --conf-file plate_env_agents.zoo

rl-zoo3 reads one ``hyperparams`` for every ``--algo``, so this module serves the entries of the algorithm named on
the command line (``--algo X`` or ``--algo=X`` in ``sys.argv``, the way ``rl_zoo3.train`` takes it; PPO's without
one): ``plate_env_agents/hyperparams/<algo>.yml`` for the algorithms in :data:`ZOO_ALGOS`. Another ``--algo`` is
refused at import with a ValueError naming the ones shipped. PPO's file is the one ``plate-env build policy`` trains
from (:func:`plate_env_agents.train.hyperparams_file`); SAC's, TD3's and A2C's are SB3's defaults, untuned (their
files say so; measured in experiments/results/zoo_algos.md). Importing this module needs PyYAML (the ``rl`` extra).
"""

from __future__ import annotations

import sys
from collections.abc import Sequence

import yaml

from plate_env_agents.train import hyperparams_file

#: The algorithms with shipped rl-zoo3 entries (the ones a Box action space admits that were measured).
ZOO_ALGOS = ("ppo", "sac", "td3", "a2c")


def algo_from_argv(argv: Sequence[str]) -> str:
    """The ``--algo`` of a command line (lower case), ``"ppo"`` when there is none."""
    for i, arg in enumerate(argv):
        if arg == "--algo" and i + 1 < len(argv):
            return argv[i + 1].lower()
        if arg.startswith("--algo="):
            return arg.partition("=")[2].lower()
    return "ppo"


def hyperparams_of(algo: str) -> dict:
    """``{env id: entry}`` of ``algo``'s installed file; ValueError naming :data:`ZOO_ALGOS` for another."""
    if algo not in ZOO_ALGOS:
        raise ValueError(f"--algo {algo}: plate_env_agents.zoo ships rl-zoo3 entries for {', '.join(ZOO_ALGOS)} "
                         "only (the others are neither tuned nor measured here); give your own --conf-file")
    return yaml.safe_load(hyperparams_file(algo).read_text())


#: ``{env id: entry}`` of the algorithm on the command line, as rl-zoo3 reads a hyperparameter file.
hyperparams: dict = hyperparams_of(algo_from_argv(sys.argv))
