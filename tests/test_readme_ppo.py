"""Issue 40 item 4: the README's Stable-Baselines3 block shows progress and sets torch's threads as the rl-zoo3
line does (``--num-threads 1``), and states its measured time beside the load it was measured at. (The block itself
runs in tests/test_readme.py, marked slow.)"""

from __future__ import annotations

import ast
import re
from pathlib import Path

README = (Path(__file__).resolve().parents[1] / "README.md").read_text()


def _ppo_block() -> str:
    blocks = re.findall(r"```python\n(.*?)```", README, re.S)
    found = [b for b in blocks if "PPO(" in b]
    assert len(found) == 1, "one README block trains PPO"
    return found[0]


def test_the_ppo_block_sets_threads_before_training_and_prints_progress():
    tree = ast.parse(_ppo_block())
    calls = [n for n in ast.walk(tree) if isinstance(n, ast.Call)]

    def name(c: ast.Call) -> str:
        return ast.unparse(c.func)

    threads = [c for c in calls if name(c) == "torch.set_num_threads"]
    ppo = [c for c in calls if name(c) == "PPO"]
    learn = [c for c in calls if name(c).endswith(".learn")]
    assert threads and ast.literal_eval(threads[0].args[0]) == 1
    assert ppo and threads[0].lineno < ppo[0].lineno < learn[0].lineno
    # SB3 prints its rollout table (steps, fps, time) after each rollout with verbose=1; progress_bar=True would
    # need the optional rich package, which the install does not pull
    kw = {k.arg: k.value for k in ppo[0].keywords}
    assert "verbose" in kw and ast.literal_eval(kw["verbose"]) >= 1
    assert not any(k.arg == "progress_bar" for c in learn for k in c.keywords)
    zoo = re.search(r"rl_zoo3\.train .*--num-threads (\d+)", README)
    assert zoo and int(zoo[1]) == 1


def test_the_readme_states_the_blocks_time_and_load():
    import json

    before = README.split(_ppo_block(), 1)[0][-500:]
    m = re.search(r"took\s+(\d+) s at load ([\d.]+)-([\d.]+).*?`(experiments/results/[\w./]+\.json)`", before, re.S)
    assert m, "the paragraph before the block states its measured time and load, citing the result"
    run = json.loads((Path(__file__).resolve().parents[1] / m[4]).read_text())
    assert round(run["wall_s"]) == int(m[1]) and run["timesteps"] == 114_688
    assert f"{run['load_avg_start']:.1f}" == m[2] and f"{run['load_avg_end']:.1f}" == m[3]
