"""A Stable-Baselines3 model zip read without unpickling anything: the policy of PPO, A2C, SAC, TD3 or DDPG.

An SB3 zip holds ``data`` (JSON) and the weights (``policy.pth``). Every ``data`` field that is not JSON-able (the
policy class, the spaces, A2C's ``policy_kwargs``, the schedules, SAC/TD3's ``train_freq``...) is stored as a
cloudpickle blob (``":serialized:"``) *and*, beside it, the readable fields of the object (a dict's JSON-able items;
for anything else ``str(value)``). ``SB3.load`` unpickles the blobs, which runs whatever code the zip carries; this
module never does. It reads:

* ``policy_class``: its ``__init__`` repr names the class (``ActorCriticPolicy``: PPO or A2C; ``SACPolicy``: SAC;
  ``TD3Policy``: TD3 or DDPG); any other is refused, naming the algorithms a Box action space admits;
* ``observation_space`` / ``action_space``: type and shape, checked against PlateRotation-v0's (an observation of
  ``k * N_FEATURES + 2`` values in [-10, 10], an action of 4 in [-1, 1]) and rebuilt as fresh Boxes;
* ``policy_kwargs``: the JSON-able values as stored; ``activation_fn`` from its repr among torch's activations
  (:data:`ACTIVATIONS`); the optimiser's class and arguments (training only) dropped; anything else refused by name;
* ``use_sde`` (on-policy algorithms).

The policy is built with SB3's own class for the algorithm's ``MlpPolicy`` and its weights are read from
``policy.pth`` with ``torch.load(weights_only=True)`` (tensors only; a pickle of anything else is refused). Every
other field (schedules, buffers, last observations, entries a newer SB3 may add) is training state: it is never
read, so it can hold nothing that runs. ``policy.predict(obs, deterministic=True)`` is then what ``model.predict``
of the trained model returns (tests/test_sb3_zips.py trains each algorithm and compares). A zip remains a file from
someone: its weights decide the actions.
"""

from __future__ import annotations

import io
import json
import zipfile
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from plate_env.core.files import check_regular
from plate_env.env.codec import N_FEATURES

#: The policy class (as ``policy_class.__init__`` names it) of each algorithm a Box action space admits.
POLICY_CLASSES = {"ppo": "ActorCriticPolicy", "a2c": "ActorCriticPolicy", "sac": "SACPolicy", "td3": "TD3Policy",
                  "ddpg": "TD3Policy"}
#: The algorithms ``sb3:ALGO:model.zip`` names, in the order the messages list them.
SB3_ALGOS = tuple(POLICY_CLASSES)
#: Algorithms whose ``policy_kwargs`` do not carry ``use_sde``: SB3 passes it to the policy separately.
ON_POLICY = ("ppo", "a2c")
#: ``torch.nn`` activations a ``policy_kwargs["activation_fn"]`` may name (its repr ``<class 'torch.nn....X'>``).
ACTIVATIONS = ("Tanh", "ReLU", "ELU", "LeakyReLU", "GELU", "SiLU", "Sigmoid", "Softplus", "Mish", "SELU", "CELU")
#: ``policy_kwargs`` entries that shape the network or its action distribution, passed on as stored (JSON values).
PLAIN_KWARGS = {"net_arch": (list, dict), "log_std_init": (int, float), "ortho_init": (bool,), "use_sde": (bool,),
                "full_std": (bool,), "use_expln": (bool,), "squash_output": (bool,), "clip_mean": (int, float),
                "n_critics": (int,), "share_features_extractor": (bool,), "normalize_images": (bool,),
                "features_extractor_kwargs": (dict,)}
#: ``policy_kwargs`` entries that only training reads (the optimiser): dropped.
TRAINING_KWARGS = ("optimizer_class", "optimizer_kwargs")
#: The submodule of each algorithm's policy that computes the deterministic action (None: the whole policy, whose
#: value head shares layers with the action's). A zip's ``policy.pth`` may hold only that submodule's tensors (named
#: ``actor.*``, as in the full policy's state dict): :func:`slim_zip` writes such zips.
ACTING_MODULE = {"ppo": None, "a2c": None, "sac": "actor", "td3": "actor", "ddpg": "actor"}
#: The members of an SB3 zip :func:`slim_zip` copies unchanged (``policy.pth`` is rewritten, the rest dropped).
KEPT_MEMBERS = ("data", "_stable_baselines3_version", "system_info.txt")


@dataclass(frozen=True)
class ZipPolicy:
    """What the loader read from a zip: the algorithm, its policy class's name and the policy's constructor
    arguments (JSON values and an activation class)."""

    algo: str
    policy_class: str
    obs_dim: int
    kwargs: dict


def read_data(path: str | Path) -> dict:
    """The zip's ``data`` (JSON). ValueError naming the file when it is not an SB3 zip."""
    check_regular(path, "sb3 model")
    try:
        with zipfile.ZipFile(path) as z:
            data = json.loads(z.read("data"))
    except (OSError, KeyError, ValueError, zipfile.BadZipFile) as exc:
        raise ValueError(f"sb3 model {str(path)!r}: not a Stable-Baselines3 zip ({exc})") from None
    if not isinstance(data, dict):
        raise ValueError(f"sb3 model {str(path)!r}: not a Stable-Baselines3 zip (its data is not a JSON object)")
    return data


def _class_name(data: dict) -> str:
    """The policy class's name as its stored ``__init__`` repr gives it (``<function X.__init__ at 0x...>``)."""
    stored = data.get("policy_class")
    init = str(stored.get("__init__", "")) if isinstance(stored, dict) else ""
    return init.split(".__init__")[0].removeprefix("<function ") if ".__init__" in init else ""


def _infer_algo(data: dict, cls: str) -> str:
    """The algorithm of a zip whose policy class is ``cls``: PPO and A2C share a class (PPO's data has
    ``clip_range``), TD3 and DDPG too (DDPG: one critic and no policy delay); they act alike."""
    if cls == "ActorCriticPolicy":
        return "ppo" if "clip_range" in data else "a2c"
    if cls == "SACPolicy":
        return "sac"
    kw = data.get("policy_kwargs")
    kw = kw if isinstance(kw, dict) else {}
    return "ddpg" if data.get("policy_delay") == 1 and kw.get("n_critics") == 1 else "td3"


def _space(where: str, key: str, value: Any) -> tuple[int, ...]:
    kind = str(value.get(":type:", "")) if isinstance(value, dict) else type(value).__name__
    raw = value.get("_shape") if isinstance(value, dict) else None
    shape = tuple(raw) if isinstance(raw, list) and all(isinstance(x, int) for x in raw) else ()
    want = f"an observation of k * {N_FEATURES} + 2 values" if key == "observation_space" else "4 values"
    ok = "gymnasium.spaces.box.Box" in kind and len(shape) == 1 and (
        (shape[0] - 2) % N_FEATURES == 0 and shape[0] > 2 if key == "observation_space" else shape[0] == 4)
    if not ok:
        raise ValueError(f"{where}: its {key.replace('_', ' ')} is {kind or '?'} of shape {shape}, not "
                         f"PlateRotation-v0's ({want}): a model for another environment")
    return shape


def _policy_kwargs(where: str, stored: Any) -> dict:
    """The constructor arguments in ``policy_kwargs`` (see the module docstring); ValueError naming an entry the
    loader cannot read."""
    if stored is None:
        return {}
    if not isinstance(stored, dict):
        raise ValueError(f"{where}: policy_kwargs is {type(stored).__name__}, not a dict")
    out: dict = {}
    for key, value in stored.items():
        if key in (":type:", ":serialized:") or key in TRAINING_KWARGS:
            continue
        if key == "activation_fn":
            name = str(value).removesuffix("'>").rpartition(".")[2]
            if not (str(value).startswith("<class 'torch.nn.modules.activation.") and name in ACTIVATIONS):
                raise ValueError(f"{where}: policy_kwargs activation_fn {value!r} is not one of torch.nn's "
                                 f"{ACTIVATIONS}")
            import torch  # only here: the shipped PPO's numpy path imports no torch

            out[key] = getattr(torch.nn, name)
        elif key == "features_extractor_class":
            if "FlattenExtractor" not in str(value):
                raise ValueError(f"{where}: policy_kwargs features_extractor_class {value!r}: only SB3's "
                                 "FlattenExtractor (MlpPolicy's) is read")
        elif key in PLAIN_KWARGS and isinstance(value, PLAIN_KWARGS[key]):
            out[key] = value
        else:
            raise ValueError(f"{where}: policy_kwargs {key} = {str(value)[:80]!r} is not one the loader reads "
                             f"(it reads {sorted(PLAIN_KWARGS)}, activation_fn and features_extractor_class): "
                             "refused rather than built differently")
    if out.get("features_extractor_kwargs"):
        raise ValueError(f"{where}: policy_kwargs features_extractor_kwargs {out['features_extractor_kwargs']!r}: "
                         "FlattenExtractor takes none")
    out.pop("features_extractor_kwargs", None)
    return out


def inspect_zip(path: str | Path, algo: str | None = None) -> ZipPolicy:
    """What :func:`load_policy` will build from ``path``, read from its JSON only. ``algo`` (one of
    :data:`SB3_ALGOS`) must match the zip's policy class; None takes the zip's. ValueError naming the file and the
    problem."""
    where = f"sb3 model {str(path)!r}"
    data = read_data(path)
    cls = _class_name(data)
    if cls not in POLICY_CLASSES.values():
        raise ValueError(f"{where}: a {cls or 'unknown'} policy; sb3: loads the MlpPolicy of the algorithms a Box "
                         f"action space admits ({', '.join(SB3_ALGOS)})")
    if algo is not None and POLICY_CLASSES[algo] != cls:
        raise ValueError(f"{where}: a {cls} policy, not the {POLICY_CLASSES[algo]} of sb3:{algo}: (name the "
                         "algorithm it was trained with, e.g. sb3:ppo:model.zip, or none: sb3:model.zip)")
    algo = algo or _infer_algo(data, cls)
    obs_shape = _space(where, "observation_space", data.get("observation_space"))
    _space(where, "action_space", data.get("action_space"))
    kwargs = _policy_kwargs(where, data.get("policy_kwargs"))
    if algo in ON_POLICY:
        use_sde = data.get("use_sde", False)
        if not isinstance(use_sde, bool):
            raise ValueError(f"{where}: use_sde = {use_sde!r} is not a bool")
        kwargs["use_sde"] = use_sde
    return ZipPolicy(algo, cls, obs_shape[0], kwargs)


def _no_schedule(_progress: float) -> float:
    return 0.0


def load_policy(path: str | Path, algo: str | None = None, device: str = "cpu"):
    """The SB3 policy in ``path`` (an SB3 ``BasePolicy`` in eval mode) and its :class:`ZipPolicy`, built as the
    module docstring says. ValueError naming the file when the zip is not one it reads or its weights are not
    tensors (or do not fit the network its JSON describes)."""
    import pickle

    import gymnasium as gym
    import stable_baselines3 as sb3
    import torch

    info = inspect_zip(path, algo)
    where = f"sb3 model {str(path)!r}"
    policy_cls = getattr(sb3, info.algo.upper()).policy_aliases["MlpPolicy"]
    obs_space = gym.spaces.Box(-10.0, 10.0, (info.obs_dim,), dtype=np.float32)
    act_space = gym.spaces.Box(-1.0, 1.0, (4,), dtype=np.float32)
    try:
        policy = policy_cls(obs_space, act_space, _no_schedule, **info.kwargs)
    except (TypeError, ValueError) as exc:  # kwargs a class does not take, a malformed net_arch
        raise ValueError(f"{where}: its policy_kwargs do not build a {info.policy_class}: {exc}") from None
    try:
        with zipfile.ZipFile(path) as z:
            blob = z.read("policy.pth")
        state = torch.load(io.BytesIO(blob), map_location=device, weights_only=True)
    except KeyError:
        raise ValueError(f"{where}: no policy.pth (the weights) in the zip") from None
    except pickle.UnpicklingError:  # torch's weights-only loader met something besides tensors
        raise ValueError(f"{where}: its weights (policy.pth) hold pickled objects besides tensors; "
                         "loading them could run code from the file: refused") from None
    if not isinstance(state, dict) or not all(isinstance(k, str) and isinstance(v, torch.Tensor)
                                              for k, v in state.items()):
        raise ValueError(f"{where}: its weights (policy.pth) are not a dict of named tensors")
    module = ACTING_MODULE[info.algo]
    slim = module is not None and bool(state) and all(k.startswith(f"{module}.") for k in state)
    target = getattr(policy, module) if slim else policy
    prefix = f"{module}." if slim else ""
    want = {prefix + k: v.shape for k, v in target.state_dict().items()}
    what = f"the {module} of the {info.policy_class}" if slim else f"the {info.policy_class}"
    missing = sorted(set(want) - set(state))
    extra = sorted(set(state) - set(want))
    shapes = [f"{k} {tuple(state[k].shape)} (needs {tuple(want[k])})" for k in sorted(set(want) & set(state))
              if tuple(state[k].shape) != tuple(want[k])]
    for label, names in (("lack", missing), ("have unknown tensors", extra), ("have wrong shapes:", shapes)):
        if names:
            raise ValueError(f"{where}: its weights do not fit {what} its data describes: they {label} "
                             f"{', '.join(names[:6])}{' ...' if len(names) > 6 else ''}")
    try:
        target.load_state_dict({k.removeprefix(prefix): v for k, v in state.items()}, strict=True)
    except (RuntimeError, TypeError, AttributeError) as exc:
        raise ValueError(f"{where}: its weights do not fit {what} its data describes: "
                         f"{str(exc).splitlines()[0]}") from None
    policy.to(device)
    policy.set_training_mode(False)
    return policy, info


def slim_zip(src: str | Path, dest: str | Path, algo: str | None = None) -> dict:
    """Write ``dest``: the SB3 zip ``src`` with only what the deterministic action needs. Kept: ``data`` (byte for
    byte), SB3's version and system info, and ``policy.pth`` holding the tensors of :data:`ACTING_MODULE`'s
    submodule (SAC, TD3, DDPG: the actor; PPO, A2C: the whole policy, unchanged). Dropped: the optimiser states,
    ``pytorch_variables.pth`` (SAC's entropy coefficient) and, for the off-policy algorithms, the critics and
    target networks. Nothing is unpickled (``torch.load(weights_only=True)``); the members' dates are fixed, so
    the same ``src`` gives the same bytes. :func:`load_policy` loads the result into the actor alone and acts as
    it does with ``src`` (tests/test_sb3_zips.py); SB3's own ``ALGO.load`` does not (it wants every optimiser
    and network back), so a zip to train on stays the full one. Returns ``{"algo", "kept", "dropped",
    "tensors", "bytes"}``. ValueError naming ``src`` when it is not a zip :func:`load_policy` reads."""
    import pickle

    import torch

    info = inspect_zip(src, algo)
    where = f"sb3 model {str(src)!r}"
    with zipfile.ZipFile(src) as z:
        names = z.namelist()
        members = {n: z.read(n) for n in KEPT_MEMBERS if n in names}
        try:
            state = torch.load(io.BytesIO(z.read("policy.pth")), map_location="cpu", weights_only=True)
        except KeyError:
            raise ValueError(f"{where}: no policy.pth (the weights) in the zip") from None
        except pickle.UnpicklingError:
            raise ValueError(f"{where}: its weights (policy.pth) hold pickled objects besides tensors: "
                             "refused") from None
    module = ACTING_MODULE[info.algo]
    if module is not None:
        state = {k: v for k, v in state.items() if k.startswith(f"{module}.")}
        if not state:
            raise ValueError(f"{where}: its policy.pth has no {module}.* tensors")
    buf = io.BytesIO()
    torch.save(state, buf)
    members["policy.pth"] = buf.getvalue()
    Path(dest).parent.mkdir(parents=True, exist_ok=True)
    with zipfile.ZipFile(dest, "w", zipfile.ZIP_DEFLATED) as z:
        for name in ("data", "policy.pth", "_stable_baselines3_version", "system_info.txt"):
            if name in members:
                z.writestr(zipfile.ZipInfo(name, date_time=(1980, 1, 1, 0, 0, 0)), members[name],
                           compress_type=zipfile.ZIP_DEFLATED)
    return {"algo": info.algo, "kept": sorted(members), "dropped": sorted(set(names) - set(members)),
            "tensors": sorted(state), "bytes": Path(dest).stat().st_size}


__all__ = ["ACTING_MODULE", "POLICY_CLASSES", "SB3_ALGOS", "ZipPolicy", "inspect_zip", "load_policy", "read_data",
           "slim_zip"]
