"""``sb3:`` loads the zip of every SB3 algorithm a Box action space admits, saved with default settings, without
unpickling anything (plate_env_agents.sb3_zip; issue 38 item 4): the loaded policy acts as the trained model's
``predict``."""

from __future__ import annotations

import base64
import json
import pickle
import zipfile

import gymnasium as gym
import numpy as np
import pytest

import plate_env  # noqa: F401 - registers the env

sb3 = pytest.importorskip("stable_baselines3")

from plate_env_agents import load_agent  # noqa: E402
from plate_env_agents.ppo import PPOAgent  # noqa: E402
from plate_env_agents.sb3_zip import SB3_ALGOS, inspect_zip  # noqa: E402

#: Steps each algorithm trains. SB3's defaults throughout (policy, network, optimiser: what the zip stores) except
#: the lengths that would make the test slow: PPO's rollout (64 steps, one minibatch, instead of 2,048) and the
#: off-policy warm-up (the last 20 steps train). The saved zips hold trained weights, the replay algorithms'
#: pickled train_freq and A2C's pickled RMSprop policy_kwargs, as default-trained ones do.
STEPS = 300
SHORTER = {"ppo": {"n_steps": 64, "batch_size": 64}, "a2c": {}, "sac": {"learning_starts": STEPS - 20},
           "td3": {"learning_starts": STEPS - 20}, "ddpg": {"learning_starts": STEPS - 20}}


@pytest.fixture(scope="module")
def zips(tmp_path_factory):
    """``{algo: (zip path, trained model)}``: each trained for STEPS steps on PlateRotationAtlas-v0 (SB3's
    defaults but :data:`SHORTER`, seed 0) and saved."""
    import torch

    out = {}
    folder = tmp_path_factory.mktemp("sb3zips")
    threads = torch.get_num_threads()
    torch.set_num_threads(1)  # the env and torch share 2 cores
    try:
        for algo in SB3_ALGOS:
            env = gym.make("PlateRotationAtlas-v0")
            model = getattr(sb3, algo.upper())("MlpPolicy", env, seed=0, device="cpu", **SHORTER[algo])
            model.learn(STEPS)
            path = folder / f"{algo}.zip"
            model.save(path)
            env.close()
            out[algo] = (path, model)
    finally:
        torch.set_num_threads(threads)
    return out


def _observations(n_random: int = 50) -> list[np.ndarray]:
    env = gym.make("PlateRotationAtlas-v0")
    obs = [env.reset(seed=s)[0] for s in range(3)]
    obs.append(env.step(np.array([0.1, -1.0, 0.0, -1.0], dtype=np.float32))[0])
    rng = np.random.default_rng(7)
    obs += list(rng.uniform(-1, 1, (n_random, env.observation_space.shape[0])).astype(np.float32))
    env.close()
    return obs


@pytest.mark.parametrize("algo", SB3_ALGOS)
def test_a_default_trained_zip_loads_and_acts_as_model_predict(zips, algo):
    path, model = zips[algo]
    with zipfile.ZipFile(path) as z:
        data = json.loads(z.read("data"))
    pickled = {k for k, v in data.items() if isinstance(v, dict) and ":serialized:" in v}
    assert "policy_class" in pickled  # SB3 pickles what it could not store as JSON; nothing of it is unpickled
    named, bare = load_agent(f"sb3:{algo}:{path}"), load_agent(f"sb3:{path}")
    assert named.algo == bare.algo == algo and named.backend == "sb3"
    for o in _observations():
        ref = np.clip(model.predict(o, deterministic=True)[0], -1, 1)
        assert np.array_equal(named.act(o), ref.astype(np.float32)), (algo, named.act(o), ref)
        assert np.array_equal(bare.act(o), named.act(o))


def test_the_fields_sb3_pickles_are_the_ones_issue_38_met(zips):
    """A2C's policy_kwargs (the RMSprop optimiser) and the off-policy train_freq are pickled in a default zip: the
    cases ``sb3:`` refused before (SB3's own load would unpickle them)."""
    def pickled(algo):
        with zipfile.ZipFile(zips[algo][0]) as z:
            return {k for k, v in json.loads(z.read("data")).items() if isinstance(v, dict) and ":serialized:" in v}

    assert "policy_kwargs" in pickled("a2c")
    assert {"train_freq"} <= pickled("sac") & pickled("td3") & pickled("ddpg")


def _doctored(src, dst, change):
    with zipfile.ZipFile(src) as zin, zipfile.ZipFile(dst, "w") as zout:
        for item in zin.namelist():
            blob = zin.read(item)
            if item == "data":
                d = json.loads(blob)
                change(d)
                blob = json.dumps(d).encode()
            zout.writestr(item, blob)
    return dst


def test_pickled_payloads_in_any_field_never_run(zips, tmp_path):
    marker = tmp_path / "pwned"

    class Evil:
        def __reduce__(self):
            return (marker.write_text, ("ran",))

    blob = base64.b64encode(pickle.dumps(Evil())).decode()

    def poison(d):
        for v in d.values():
            if isinstance(v, dict) and ":serialized:" in v:
                v[":serialized:"] = blob

    for algo in SB3_ALGOS:
        agent = PPOAgent(_doctored(zips[algo][0], tmp_path / f"{algo}.zip", poison), deterministic=False)
        agent.act(_observations(0)[0])
    assert not marker.exists(), "a pickled field ran"


@pytest.mark.parametrize("change, needle", [
    (lambda d: d["policy_class"].__setitem__("__init__", "<function DQNPolicy.__init__ at 0x0>"),
     "a DQNPolicy policy; sb3: loads the MlpPolicy of the algorithms a Box action space admits"),
    (lambda d: d["policy_kwargs"].__setitem__("activation_fn", "<class 'os.system'>"),
     "activation_fn \"<class 'os.system'>\" is not one of torch.nn's"),
    (lambda d: d["policy_kwargs"].__setitem__("features_extractor_class", "<class 'my.Extractor'>"),
     "only SB3's FlattenExtractor"),
    (lambda d: d["policy_kwargs"].__setitem__("dropout", 0.5), "policy_kwargs dropout = '0.5' is not one"),
    (lambda d: d["policy_kwargs"].__setitem__("net_arch", [7, 7]), "its weights do not fit the ActorCriticPolicy"),
])
def test_what_the_loader_cannot_read_is_refused_by_name(zips, tmp_path, change, needle):
    bad = _doctored(zips["a2c"][0], tmp_path / "bad.zip", change)
    with pytest.raises(ValueError, match="bad.zip") as err:
        PPOAgent(bad, deterministic=False)
    assert needle in str(err.value), str(err.value)


def test_an_algorithm_spec_it_does_not_load_is_one_clear_line(zips):
    with pytest.raises(ValueError, match="'dqn' is not an algorithm sb3: loads; choose one of ppo, a2c, sac, td3"):
        load_agent(f"sb3:dqn:{zips['sac'][0]}")
    with pytest.raises(ValueError, match="a SACPolicy policy, not the TD3Policy of sb3:td3:"):
        load_agent(f"sb3:td3:{zips['sac'][0]}")
    assert load_agent(f"sb3:SAC:{zips['sac'][0]}").algo == "sac"
    assert inspect_zip(zips["ddpg"][0]).algo == "ddpg" and inspect_zip(zips["td3"][0]).algo == "td3"


def _with_weights(src, dst, change):
    """``src`` with its policy.pth's state dict changed by ``change`` (tensors only, as SB3 saves them)."""
    import io

    import torch

    with zipfile.ZipFile(src) as zin, zipfile.ZipFile(dst, "w") as zout:
        for item in zin.namelist():
            blob = zin.read(item)
            if item == "policy.pth":
                state = torch.load(io.BytesIO(blob), weights_only=True)
                change(state)
                buf = io.BytesIO()
                torch.save(state, buf)
                blob = buf.getvalue()
            zout.writestr(item, blob)
    return dst


@pytest.mark.parametrize("algo", ["sac", "td3", "ddpg", "ppo"])
def test_a_slim_zip_holds_only_the_acting_tensors_and_acts_as_the_full_one(zips, algo, tmp_path):
    """slim_zip (issue 38: the leaderboard's SAC/TD3 zips shipped at a tenth of their size) keeps ``data`` and the
    actor (SAC, TD3, DDPG) or the whole policy (PPO); load_policy loads the actor alone, and the deterministic
    action is the full zip's on a few hundred observations."""
    import io

    import torch

    from plate_env_agents.sb3_zip import load_policy, slim_zip

    path, _ = zips[algo]
    slim = tmp_path / f"{algo}_slim.zip"
    info = slim_zip(path, slim)
    with zipfile.ZipFile(slim) as z, zipfile.ZipFile(path) as zfull:
        assert set(z.namelist()) == {"data", "policy.pth", "_stable_baselines3_version", "system_info.txt"}
        assert z.read("data") == zfull.read("data")
        state = torch.load(io.BytesIO(z.read("policy.pth")), weights_only=True)
        full_state = torch.load(io.BytesIO(zfull.read("policy.pth")), weights_only=True)
    if algo == "ppo":
        assert set(state) == set(full_state)
    else:
        assert state and all(k.startswith("actor.") for k in state) and set(state) < set(full_state)
        assert any(k.startswith("critic") for k in full_state)
        assert slim.stat().st_size < path.stat().st_size / 2, (slim.stat().st_size, path.stat().st_size)
    assert info["tensors"] == sorted(state) and "policy.pth" in info["kept"]
    assert [n for n in info["dropped"] if n.endswith("optimizer.pth")]
    obs = np.stack(_observations(300))
    full_pol, slim_pol = load_policy(path)[0], load_policy(slim)[0]
    np.testing.assert_array_equal(slim_pol.predict(obs, deterministic=True)[0],
                                  full_pol.predict(obs, deterministic=True)[0])
    full_agent, slim_agent = load_agent(f"sb3:{algo}:{path}"), load_agent(f"sb3:{slim}")
    assert slim_agent.algo == algo
    for o in obs[:20]:
        assert np.array_equal(slim_agent.act(o), full_agent.act(o))


@pytest.mark.parametrize("algo, change, needle", [
    ("sac", lambda s: s.pop("actor.mu.weight"), "they lack actor.mu.weight"),
    ("td3", lambda s: s.pop("actor.mu.4.bias"), "they lack actor.mu.4.bias"),
    ("sac", lambda s: s.__setitem__("actor.mu.bias", s["actor.mu.bias"][:3].clone()),
     "actor.mu.bias (3,) (needs (4,))"),
    ("td3", lambda s: s.__setitem__("actor.extra.weight", s["actor.mu.0.bias"].clone()),
     "unknown tensors actor.extra.weight"),
    ("sac", lambda s: s.pop("critic.qf0.0.weight"), "its weights do not fit the SACPolicy"),
])
def test_a_slim_zip_missing_or_misshaping_an_actor_tensor_is_refused_by_name(zips, tmp_path, algo, change, needle):
    from plate_env_agents.sb3_zip import slim_zip

    slim = slim_zip(zips[algo][0], tmp_path / "slim.zip") and tmp_path / "slim.zip"
    src = slim if needle.startswith(("they", "actor", "unknown")) else zips[algo][0]
    bad = _with_weights(src, tmp_path / "bad.zip", change)
    with pytest.raises(ValueError, match="bad.zip") as err:
        load_agent(f"sb3:{algo}:{bad}")
    assert needle in str(err.value), str(err.value)


def test_a_zip_without_sidecar_on_an_env_of_other_settings_is_refused_saying_what_to_write(zips, tmp_path):
    """Without MODEL.json the training settings are unknown: on the env's defaults the zip plays as before, on an
    env whose amplitudes differ (PlateRotationAtlas-v1's) it is refused, naming the sidecar to write, instead of
    being scored silently in PlateRotation-v0's coordinates; with the sidecar it plays."""
    import shutil

    from plate_env.env.protocol import ProbeContext

    path = shutil.copyfile(zips["sac"][0], tmp_path / "sac.zip")
    agent = load_agent(f"sb3:sac:{path}")
    default = gym.make("PlateRotationAtlas-v0")
    default.reset(seed=0)
    agent.reset(ProbeContext.from_env(default), np.random.default_rng(0))  # the defaults: no sidecar needed
    default.close()
    env = gym.make("PlateRotationAtlas-v1")
    env.reset(seed=0)
    context = ProbeContext.from_env(env)
    assert tuple(context.amplitudes_deg) != (3.0, 12.0)
    with pytest.raises(ValueError, match="has no sidecar sac.json") as err:
        agent.reset(context, np.random.default_rng(0))
    assert "env_kwargs" in str(err.value) and "sac.json" in str(err.value)
    kwargs = {"amplitudes_deg": list(context.amplitudes_deg), "f_band_hz": list(context.f_band_hz),
              "measure_range_s": list(context.measure_range_s)}
    path.with_suffix(".json").write_text(json.dumps({"env_kwargs": kwargs}))
    load_agent(f"sb3:sac:{path}").reset(context, np.random.default_rng(0))
    env.close()


def test_the_record_key_follows_the_sidecars_settings(zips, tmp_path):
    """The bench's episode cache names an sb3 agent by its zip's hash and the training settings its sidecar gives
    (the agent's public options): a changed sidecar (other amplitudes) makes a new key, an unchanged setting (a note
    added) keeps it. (Issue 38's report that an edited sidecar reused stale episodes: it does not; this keeps it
    so.)"""
    import shutil

    from plate_env.bench.fingerprint import agent_fingerprint

    path = shutil.copyfile(zips["td3"][0], tmp_path / "td3.zip")
    bare = agent_fingerprint(load_agent(f"sb3:td3:{path}"))
    path.with_suffix(".json").write_text(json.dumps({"note": "how it was made", "env_kwargs": {}}))
    assert agent_fingerprint(load_agent(f"sb3:td3:{path}")) == bare
    path.with_suffix(".json").write_text(json.dumps({"env_kwargs": {"amplitudes_deg": [2.0, 8.0, 14.0]}}))
    moved = agent_fingerprint(load_agent(f"sb3:td3:{path}"))
    assert moved != bare and moved["extra"].startswith(bare["extra"].split()[0])
