"""examples/cleanrl_ppo.py, the CleanRL-style single-file PPO, runs on the installed gymnasium 1.x against
PlateRotationAtlas-v0 (issue 41 item 7): two short updates in a subprocess, with the episodes' final infos read."""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import gymnasium as gym
import pytest

pytest.importorskip("torch")
ROOT = Path(__file__).resolve().parents[1]


def test_the_cleanrl_style_example_trains_briefly_on_gymnasium_1(tmp_path):
    assert int(gym.__version__.split(".")[0]) >= 1
    out = tmp_path / "agent.pt"
    done = subprocess.run([sys.executable, str(ROOT / "examples" / "cleanrl_ppo.py"), "--total-timesteps", "256",
                           "--num-steps", "64", "--num-minibatches", "4", "--update-epochs", "2", "--save", str(out)],
                          capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr[-2000:]
    lines = re.findall(r"iteration (\d)/2: steps (\d+), episodes (\d+), mean return (\S+), median relative error "
                       r"(\S+),", done.stdout)
    assert [(i, s) for i, s, *_ in lines] == [("1", "128"), ("2", "256")], done.stdout
    for _, _, episodes, ret, err in lines:  # episodes ended and their final infos were read
        assert int(episodes) > 0 and float(ret) < 0 and float(err) >= 0, done.stdout
    assert out.stat().st_size > 0
