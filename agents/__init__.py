"""Probing agents: the paper's grid sweep, a coarse-to-fine heuristic, Bayesian design, a trained PPO policy.

Installed as ``plate_env_agents`` (the folder is ``agents/``). They follow the protocol of
:mod:`plate_env.env.protocol`; :func:`load_agent` also loads an agent of your own from a file or a Stable-Baselines3
model, by the specs ``plate-env bench --agent`` takes.
"""

from __future__ import annotations

import ast
import hashlib
import importlib.util
import sys
from pathlib import Path

from plate_env.core.files import check_regular
from plate_env.core.registry import Registry
from plate_env.env.protocol import Agent, Probe, ProbeContext, check_agent

#: The shipped agents, by name (the one list: the command line and :func:`load_agent` read it).
AGENTS = Registry("agent", {"grid": "plate_env_agents.grid:GridAgent",
                            "coarse_to_fine": "plate_env_agents.coarse_to_fine:CoarseToFineAgent",
                            "bayes": "plate_env_agents.bayes:BayesAgent", "ppo": "plate_env_agents.ppo:PPOAgent"})
AGENT_NAMES = AGENTS.names


def make_agent(name: str, **options) -> Agent:
    """Create a shipped agent by name (:data:`AGENTS`); options go to its constructor. A spec :func:`load_agent`
    takes (``sb3:model.zip``, ``path/to/file.py:MyAgent``, ``grid:n=30``) is loaded by it (without further
    options)."""
    if isinstance(name, str) and ":" in name:
        if options:
            raise ValueError(f"make_agent({name!r}, ...): a spec carries its own options (name:key=value,...)")
        return load_agent(name)
    cls = AGENTS.load(name)
    forward = options.pop("forward", None) if name != "bayes" else None  # bayes designs on it too: its argument
    agent = cls(**options)
    if forward is not None:
        from plate_env.identify.estimators import READS_FORWARD_MODEL

        if not READS_FORWARD_MODEL[agent.method]:
            raise ValueError(f"forward = {forward!r}: agent {name!r} estimates by method {agent.method!r}, which reads "
                             "no forward model (give method=atlas)")
        agent.forward = check_forward_name(forward)
    return agent


def check_forward_name(name) -> str:
    """``name`` if it names a shipped forward model, else ValueError listing them."""
    from plate_env.surrogate.catalog import read_catalog

    shipped = sorted(read_catalog())
    if not isinstance(name, str) or name not in shipped:
        raise ValueError(f"forward = {name!r}: no such forward model; shipped: {shipped}")
    return name


def _value(text: str):
    try:
        return ast.literal_eval(text)
    except (ValueError, SyntaxError):
        return text


def _options(text: str, spec: str) -> dict:
    out = {}
    for item in filter(None, text.split(",")):
        key, eq, value = item.partition("=")
        if not eq or not key.strip().isidentifier():
            raise ValueError(f"agent {spec!r}: options are key=value pairs separated by commas, got {item!r}")
        out[key.strip()] = _value(value.strip())
    return out


def load_file_agent(path: str | Path, class_name: str):
    """An instance (no arguments) of class ``class_name`` defined in the Python file ``path``."""
    path = check_regular(path, "agent file")
    module_name = f"plate_env_user_agent_{hashlib.sha256(str(path.resolve()).encode()).hexdigest()[:12]}"
    module = sys.modules.get(module_name)
    if module is None:
        spec = importlib.util.spec_from_file_location(module_name, path)
        module = importlib.util.module_from_spec(spec)
        sys.modules[module_name] = module
        try:
            spec.loader.exec_module(module)
        except BaseException as exc:  # noqa: BLE001 - a user's file: SyntaxError, ImportError, sys.exit, anything
            del sys.modules[module_name]
            if isinstance(exc, KeyboardInterrupt):
                raise
            raise ValueError(f"agent file {str(path)!r} cannot be imported: {type(exc).__name__}: {exc}") from None
    cls = getattr(module, class_name, None)
    if not isinstance(cls, type):
        found = sorted(k for k, v in vars(module).items() if isinstance(v, type) and hasattr(v, "next_probe"))
        raise ValueError(f"agent file {str(path)!r} has no class {class_name!r} (agent classes there: {found})")
    try:
        return cls()
    except Exception as exc:  # noqa: BLE001 - a user's constructor: arguments it needs, anything it raises
        raise ValueError(f"agent {class_name!r} from {str(path)!r} cannot be made without arguments: "
                         f"{type(exc).__name__}: {exc}") from None


def load_agent(spec: str):
    """An agent from a spec (what ``plate-env bench --agent`` takes):

    * ``bayes``, ``grid``, ``coarse_to_fine``, ``ppo``, with options ``name:key=value,...``
      (``grid:n=30,method=atlas``); every one takes ``forward=NAME``, the shipped forward model its estimate is made
      through (bayes designs its probes on it too; default: the episode physics' own), e.g. ``ppo:forward=lab``;
    * ``path/to/file.py:MyAgent``: an instance of class ``MyAgent`` from that file, made without arguments;
    * ``sb3:model.zip`` or ``sb3:ALGO:model.zip`` (ALGO: ppo, a2c, sac, td3 or ddpg): a Stable-Baselines3 policy
      trained on PlateRotation-v0, loaded without unpickling anything (:class:`plate_env_agents.ppo.PPOAgent`; the
      algorithm the zip's policy class names unless one is given, then checked against it).

    The agent is checked against the protocol (:func:`plate_env.env.protocol.check_agent`); a bad spec is a ValueError
    naming it."""
    if not isinstance(spec, str) or not spec:
        raise ValueError(f"agent spec {spec!r}: give a name, file.py:Class or sb3:model.zip")
    if spec.startswith("sb3:"):
        from plate_env_agents.ppo import SB3_ALGOS, PPOAgent

        rest = spec[4:]
        head, sep, path = rest.partition(":")
        algo = head.lower() if sep and head.lower() in SB3_ALGOS else None
        if algo is None:
            path = rest
            if sep and head.isidentifier() and not Path(rest).exists():
                raise ValueError(f"agent {spec!r}: {head!r} is not an algorithm sb3: loads; choose one of "
                                 f"{', '.join(SB3_ALGOS)} (the SB3 algorithms a Box action space admits), "
                                 "or none (sb3:model.zip takes the zip's)")
        agent = PPOAgent(path=path, algo=algo)
        agent.name = spec
    else:
        head, sep, tail = spec.partition(":")
        if head.endswith(".py"):
            agent = load_file_agent(head, tail) if sep and tail.isidentifier() else None
            if agent is None:
                raise ValueError(f"agent {spec!r}: a file agent is path/to/file.py:ClassName")
        elif head in AGENT_NAMES:
            try:
                agent = make_agent(head, **_options(tail, spec))
            except (TypeError, ValueError) as exc:  # an unknown option, a value of the wrong type or range
                raise ValueError(f"agent {spec!r}: {exc}") from None
        else:
            raise ValueError(f"unknown agent {spec!r}; choose one of {AGENT_NAMES} (options: name:key=value,...), "
                             "path/to/file.py:ClassName or sb3:model.zip")
    return check_agent(agent, where=f"agent {spec!r}")


__all__ = ["AGENTS", "AGENT_NAMES", "Agent", "Probe", "ProbeContext", "load_agent", "load_file_agent", "make_agent"]
