"""CleanRL-style single-file PPO (continuous actions) on PlateRotationAtlas-v0, for gymnasium 1.x.

CleanRL's own scripts pin gymnasium 0.29 (plate-env needs >= 1.0); this file follows its ``ppo_continuous_action.py``
(one file, a vector env, GAE, clipped surrogate, minibatch epochs) on gymnasium >= 1.1's vector API: ``SyncVectorEnv``
with ``AutoresetMode.SAME_STEP``, so that a finished sub-env's next observation is the new episode's first one and
its last info is in ``infos["final_info"]``, as in CleanRL's loop. Needs torch (the ``rl`` extra installs it)::

    python examples/cleanrl_ppo.py --total-timesteps 4096 --seed 1

Prints the mean return and the median relative error of omega_n over the episodes that ended in each update, and
saves the policy's state dict with ``--save PATH``. A few thousand steps take about a minute on two cores; it is a
starting point to edit, not the shipped policy (``plate-env build policy`` trains that, docs/training.md).
"""

from __future__ import annotations

import argparse
import time

import gymnasium as gym
import numpy as np
import torch
from torch import nn
from torch.distributions.normal import Normal

import plate_env  # noqa: F401 - registers PlateRotationAtlas-v0


def parse_args(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--env-id", default="PlateRotationAtlas-v0")
    p.add_argument("--seed", type=int, default=1)
    p.add_argument("--total-timesteps", type=int, default=4096)
    p.add_argument("--num-envs", type=int, default=2)
    p.add_argument("--num-steps", type=int, default=256, help="steps per env per rollout")
    p.add_argument("--learning-rate", type=float, default=3e-4)
    p.add_argument("--gamma", type=float, default=0.99)
    p.add_argument("--gae-lambda", type=float, default=0.95)
    p.add_argument("--num-minibatches", type=int, default=8)
    p.add_argument("--update-epochs", type=int, default=10)
    p.add_argument("--clip-coef", type=float, default=0.2)
    p.add_argument("--ent-coef", type=float, default=0.0)
    p.add_argument("--vf-coef", type=float, default=0.5)
    p.add_argument("--max-grad-norm", type=float, default=0.5)
    p.add_argument("--save", default=None, help="write the agent's state dict here")
    return p.parse_args(argv)


def make_env(env_id: str):
    def thunk():
        return gym.wrappers.RecordEpisodeStatistics(gym.make(env_id))
    return thunk


def layer_init(layer, std=2 ** 0.5, bias_const=0.0):
    nn.init.orthogonal_(layer.weight, std)
    nn.init.constant_(layer.bias, bias_const)
    return layer


class Agent(nn.Module):
    def __init__(self, obs_dim: int, act_dim: int):
        super().__init__()
        self.critic = nn.Sequential(layer_init(nn.Linear(obs_dim, 64)), nn.Tanh(), layer_init(nn.Linear(64, 64)),
                                    nn.Tanh(), layer_init(nn.Linear(64, 1), std=1.0))
        self.actor_mean = nn.Sequential(layer_init(nn.Linear(obs_dim, 64)), nn.Tanh(), layer_init(nn.Linear(64, 64)),
                                        nn.Tanh(), layer_init(nn.Linear(64, act_dim), std=0.01))
        self.actor_logstd = nn.Parameter(torch.full((1, act_dim), -0.5))

    def get_value(self, x):
        return self.critic(x)

    def get_action_and_value(self, x, action=None):
        mean = self.actor_mean(x)
        probs = Normal(mean, self.actor_logstd.expand_as(mean).exp())
        if action is None:
            action = probs.sample()
        return action, probs.log_prob(action).sum(1), probs.entropy().sum(1), self.critic(x)


def main(argv=None) -> dict:
    args = parse_args(argv)
    batch_size = args.num_envs * args.num_steps
    minibatch_size = batch_size // args.num_minibatches
    num_iterations = max(args.total_timesteps // batch_size, 1)
    rng = np.random.default_rng(args.seed)  # minibatch order
    torch.manual_seed(args.seed)
    torch.set_num_threads(1)

    envs = gym.vector.SyncVectorEnv([make_env(args.env_id) for _ in range(args.num_envs)],
                                    autoreset_mode=gym.vector.AutoresetMode.SAME_STEP)
    obs_dim, act_dim = envs.single_observation_space.shape[0], envs.single_action_space.shape[0]
    low, high = envs.single_action_space.low, envs.single_action_space.high
    agent = Agent(obs_dim, act_dim)
    optimizer = torch.optim.Adam(agent.parameters(), lr=args.learning_rate, eps=1e-5)

    obs = torch.zeros((args.num_steps, args.num_envs, obs_dim))
    actions = torch.zeros((args.num_steps, args.num_envs, act_dim))
    logprobs, rewards, dones, values = (torch.zeros((args.num_steps, args.num_envs)) for _ in range(4))
    next_obs = torch.as_tensor(envs.reset(seed=args.seed)[0])
    next_done = torch.zeros(args.num_envs)
    start, history = time.time(), {"returns": [], "rel_errors": []}
    for iteration in range(1, num_iterations + 1):
        ended_returns, ended_errors = [], []
        for step in range(args.num_steps):
            obs[step], dones[step] = next_obs, next_done
            with torch.no_grad():
                action, logprob, _, value = agent.get_action_and_value(next_obs)
            values[step], actions[step], logprobs[step] = value.flatten(), action, logprob
            o, r, term, trunc, infos = envs.step(np.clip(action.numpy(), low, high))
            rewards[step] = torch.as_tensor(r, dtype=torch.float32)
            next_obs, next_done = torch.as_tensor(o), torch.as_tensor(term | trunc, dtype=torch.float32)
            if "final_info" in infos:  # the last info of each sub-env whose episode ended in this step
                final, mask = infos["final_info"], infos["_final_info"]
                ended_returns += list(final["episode"]["r"][mask])
                ended_errors += list(final["relative_error"][mask])
        with torch.no_grad():  # generalized advantage estimation
            next_value = agent.get_value(next_obs).reshape(1, -1)
            advantages = torch.zeros_like(rewards)
            lastgaelam = 0
            for t in reversed(range(args.num_steps)):
                nonterminal = 1.0 - (next_done if t == args.num_steps - 1 else dones[t + 1])
                nextvalues = next_value if t == args.num_steps - 1 else values[t + 1]
                delta = rewards[t] + args.gamma * nextvalues * nonterminal - values[t]
                advantages[t] = lastgaelam = delta + args.gamma * args.gae_lambda * nonterminal * lastgaelam
            returns = advantages + values
        b_obs, b_actions = obs.reshape(-1, obs_dim), actions.reshape(-1, act_dim)
        b_logprobs, b_adv, b_ret = logprobs.reshape(-1), advantages.reshape(-1), returns.reshape(-1)
        idx = np.arange(batch_size)
        for _ in range(args.update_epochs):
            rng.shuffle(idx)
            for lo in range(0, batch_size, minibatch_size):
                mb = idx[lo:lo + minibatch_size]
                _, newlogprob, entropy, newvalue = agent.get_action_and_value(b_obs[mb], b_actions[mb])
                ratio = (newlogprob - b_logprobs[mb]).exp()
                adv = (b_adv[mb] - b_adv[mb].mean()) / (b_adv[mb].std() + 1e-8)
                pg_loss = torch.max(-adv * ratio, -adv * torch.clamp(ratio, 1 - args.clip_coef, 1 + args.clip_coef))
                loss = (pg_loss.mean() - args.ent_coef * entropy.mean()
                        + args.vf_coef * 0.5 * ((newvalue.view(-1) - b_ret[mb]) ** 2).mean())
                optimizer.zero_grad()
                loss.backward()
                nn.utils.clip_grad_norm_(agent.parameters(), args.max_grad_norm)
                optimizer.step()
        err = np.asarray(ended_errors, dtype=float)
        err = np.where(np.isnan(err), np.inf, err)  # an episode without an estimate: an infinite error
        history["returns"].append(float(np.mean(ended_returns)) if ended_returns else float("nan"))
        history["rel_errors"].append(float(np.median(err)) if err.size else float("nan"))
        print(f"iteration {iteration}/{num_iterations}: steps {iteration * batch_size}, episodes {len(err)}, "
              f"mean return {history['returns'][-1]:.3f}, median relative error {history['rel_errors'][-1]:.3f}, "
              f"{time.time() - start:.0f} s", flush=True)
    envs.close()
    if args.save:
        torch.save(agent.state_dict(), args.save)
    return history


if __name__ == "__main__":
    main()
