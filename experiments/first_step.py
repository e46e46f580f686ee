"""Start-up of an env id in a fresh process (issue 35: "the first step after gym.make stays <= 0.05 s").

    python experiments/first_step.py [IDS...]

For each id, a new interpreter times ``import gymnasium, plate_env``, ``gym.make(id)``, ``reset`` and the first
two steps (a 20 Hz and a 22 Hz probe at 3 deg, 1 s windows). Prints one line per id and writes
``experiments/results/first_step.md``; one run, wall-clock seconds.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

CHILD = """
import json, sys, time
t0 = time.perf_counter()
import gymnasium as gym, plate_env
t1 = time.perf_counter()
env = gym.make(sys.argv[1])
t2 = time.perf_counter()
env.reset(seed=0)
t3 = time.perf_counter()
env.step(env.unwrapped.encode_action(20.0, 3.0, 1.0))
t4 = time.perf_counter()
env.step(env.unwrapped.encode_action(22.0, 3.0, 1.0))
t5 = time.perf_counter()
print(json.dumps({"import_s": t1 - t0, "make_s": t2 - t1, "reset_s": t3 - t2, "step1_s": t4 - t3, "step2_s": t5 - t4}))
"""


def main(argv: list[str] | None = None) -> None:
    ids = (argv if argv is not None else sys.argv[1:]) or ["PlateRotationAtlas-v0", "PlateRotationAtlas-v1",
                                                           "PlateRotation-v0"]
    rows = {}
    for env_id in ids:
        done = subprocess.run([sys.executable, "-c", CHILD, env_id], capture_output=True, text=True, check=True)
        rows[env_id] = json.loads(done.stdout.splitlines()[-1])
        print(env_id, {k: round(v, 4) for k, v in rows[env_id].items()}, flush=True)
    lines = ["# First step after gym.make, fresh process (issue 35)", "",
             f"Command: `python experiments/first_step.py {' '.join(ids)}`; one run, load {os.getloadavg()[0]:.1f}.",
             "", "| id | import s | make s | reset s | first step s | second step s |", "|---|---|---|---|---|---|"]
    lines += [f"| {i} | {r['import_s']:.3f} | {r['make_s']:.3f} | {r['reset_s']:.4f} | {r['step1_s']:.3f} | "
              f"{r['step2_s']:.4f} |" for i, r in rows.items()]
    out = Path(__file__).parent / "results" / "first_step.md"
    out.write_text("\n".join(lines) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    main()
