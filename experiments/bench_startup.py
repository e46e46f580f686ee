"""Start-up costs, measured in fresh processes: the PPO agent to its first action, and the first PyBullet probe.

    python experiments/bench_startup.py [--repeats 5] [--no-pybullet]

PPO: ``make_agent("ppo")`` then one action on an atlas env, in ``--repeats`` fresh interpreters, with the agent's
numpy forward pass (the shipped export) and, for comparison, through Stable-Baselines3 (torch); medians and their
ratio. PyBullet: one fresh process runs an env's first step and splits it into the omega_n calibration of the
object (ring-downs), the scene build and the probe itself. Writes experiments/results/bench_startup.md (the load
average is in it: wall times on a shared machine are noisy).
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
from pathlib import Path

PPO_CODE = """
import time, json
model = None
if {force_sb3}:  # the SB3 path: the shipped zip and its provenance copied alone, without the numpy export beside it
    import importlib.util, shutil, tempfile
    from pathlib import Path
    shipped = Path(importlib.util.find_spec("plate_env_agents").submodule_search_locations[0]) / "models"
    model = Path(tempfile.mkdtemp()) / "ppo_plate.zip"
    for suffix in (".zip", ".json"):
        shutil.copy(shipped / ("ppo_plate" + suffix), model.with_suffix(suffix))
t0 = time.perf_counter()
import numpy as np
from plate_env_agents import make_agent
from plate_env.env.rotation import PlateRotationEnv
from plate_env.env.protocol import ProbeContext
t1 = time.perf_counter()
agent = make_agent("ppo") if model is None else make_agent("ppo", path=model)
t2 = time.perf_counter()
env = PlateRotationEnv(physics="atlas")
obs, _ = env.reset(seed=0)
t3 = time.perf_counter()
agent.reset(ProbeContext.from_env(env), np.random.default_rng(0))
agent.next_probe(env.table(), obs)
t4 = time.perf_counter()
print(json.dumps({{"imports": t1 - t0, "make_agent": t2 - t1, "env": t3 - t2, "first_action": t4 - t3,
                   "agent_total": (t2 - t1) + (t4 - t3), "backend": agent.backend}}))
"""

def run(code: str) -> dict:
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    return json.loads(done.stdout.strip().splitlines()[-1])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--no-pybullet", action="store_true")
    args = ap.parse_args()
    load = os.getloadavg()[0]
    rows = {}
    for label, force in (("numpy (shipped export)", False), ("Stable-Baselines3 (torch)", True)):
        rs = [run(PPO_CODE.format(force_sb3=force)) for _ in range(args.repeats)]
        rows[label] = {k: statistics.median(r[k] for r in rs) for k in ("imports", "make_agent", "first_action",
                                                                         "agent_total")}
        print(label, rows[label], flush=True)
    lines = ["# Start-up costs", "", f"Regenerate: `python experiments/bench_startup.py`. Load average {load:.1f} at "
             f"the start on the shared 2-core machine (wall times scale with it).", "",
             f"## PPO agent: `make_agent(\"ppo\")` to its first action (median of {args.repeats} fresh processes)", "",
             "| forward pass | import plate_env + agents, s | make_agent, s | first action, s | agent total, s |",
             "|---|---|---|---|---|"]
    for label, r in rows.items():
        lines.append(f"| {label} | {r['imports']:.2f} | {r['make_agent']:.3f} | {r['first_action']:.4f} | "
                     f"{r['agent_total']:.3f} |")
    a, b = (rows[k]["agent_total"] for k in rows)
    lines += ["", f"Ratio (torch / numpy): {b / a:.0f}x."]
    if not args.no_pybullet:
        # the measurement of experiments/bench_speed.py (one fresh process), under this report's names
        speed = str(Path(__file__).with_name("bench_speed.py"))
        done = subprocess.run([sys.executable, speed, "--measure", "pybullet"], capture_output=True, text=True,
                              check=True)
        m = json.loads(done.stdout.strip().splitlines()[-1])
        p = {"env_and_reset": m["env_and_reset_s"], "first_step": m["first_probe_s"], "ringdowns": m["ringdowns"],
             "calibration": m["calibration_s"], "scene_build": m["scene_build_s"], "sim_s": m["sim_s"]}
        print(p, flush=True)
        probe = p["first_step"] - p["calibration"] - p["scene_build"]
        lines += ["", "## PyBullet: an env's first step (one fresh process, omega_n = 15 pi, 18 Hz, 0.6 s window)", "",
                  "| env + reset, s | first step, s | of which omega_n calibration (ring-downs) | scene builds | "
                  "the probe | simulated s |", "|---|---|---|---|---|---|",
                  f"| {p['env_and_reset']:.2f} | {p['first_step']:.1f} | {p['calibration']:.1f} s "
                  f"({p['ringdowns']} ring-downs) | {p['scene_build']:.2f} s | {probe:.1f} s | {p['sim_s']:.2f} |",
                  "", "The calibration of a new object's spring stiffness by ring-downs (cached per process) is what "
                  "the first step costs beyond the scene build and the probe itself; see the report of issue 14."]
    out = Path("experiments/results/bench_startup.md")
    out.write_text("\n".join(lines) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    main()
