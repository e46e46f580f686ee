"""rl-zoo3's view of the hyperparameters installed with this package: ``--conf-file plate_env_agents.zoo`` (rl-zoo3
imports a ``--conf-file`` that is not a ``.yml``/``.py`` path as a module and reads its ``hyperparams``)::

    python -m rl_zoo3.train --algo ppo --env PlateRotation-v0 --gym-packages plate_env --conf-file plate_env_agents.zoo

``hyperparams`` holds the PPO entries of ``plate_env_agents/hyperparams/ppo.yml``, the file ``plate-env build policy``
trains from (:func:`plate_env_agents.train.hyperparams_file`). Importing this module needs PyYAML (the ``rl``
extra; rl-zoo3 depends on it).
"""

from __future__ import annotations

import yaml

from plate_env_agents.train import hyperparams_file

#: ``{env id: entry}`` of the installed PPO hyperparameters, as rl-zoo3 reads a hyperparameter file.
hyperparams: dict = yaml.safe_load(hyperparams_file("ppo").read_text())
