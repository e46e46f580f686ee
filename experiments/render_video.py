"""What rendering costs and how long an episode's video runs (issue 38 item 6), and the frames in docs/env.md.

    python experiments/render_video.py [--episodes 20] [--docs]

The shipped ``bayes`` agent plays ``PlateRotationAtlas-v0`` episodes (seeds 0..N-1) with
``render_mode="rgb_array_list"``; the CPU time (``time.process_time``: on a shared machine the wall clock measures
the other users) spent building each step's scene (its estimate included) and drawing its frames, over the frames
drawn, is the cost per frame in an episode. The drawing alone is timed on the last episode's final scene
(:func:`plate_env.env.render.probe_frames`, :func:`plate_env.env.render.draw_frame`). Writes
experiments/results/render_video.md; ``--docs`` also writes docs/img/render_probe.png, render_unstable.png and
render_episode.gif from seed 1's episode.
"""

from __future__ import annotations

import argparse
import os
import time
from pathlib import Path

import gymnasium as gym
import numpy as np

import plate_env  # noqa: F401 - registers the ids
from plate_env.env import render
from plate_env.env.episode import run_episode
from plate_env_agents import make_agent

ROOT = Path(__file__).resolve().parents[1]


SPENT = [0.0]  # CPU seconds in the env's rendering hooks


def timed(fn):
    def wrapper(*args, **kwargs):
        t0 = time.process_time()
        try:
            return fn(*args, **kwargs)
        finally:
            SPENT[0] += time.process_time() - t0
    return wrapper


def play(seed: int):
    """One bayes episode with rgb_array_list: (CPU s in the rendering hooks, frames, the env)."""
    env = gym.make("PlateRotationAtlas-v0", render_mode="rgb_array_list")
    agent = make_agent("bayes")
    SPENT[0] = 0.0
    run_episode(env, agent, seed=seed)
    frames = env.render()
    return SPENT[0], frames, env.unwrapped


def docs_images(frames: list[np.ndarray], table) -> list[str]:
    """The frames docs/env.md shows: an unstable probe at 3/4 of its period, the last 12-deg stable probe at 1/4."""
    from PIL import Image

    start = [1 + k * render.FRAMES_PER_PROBE for k in range(len(table))]
    unstable = next(k for k in range(len(table)) if table.unstable[k])
    stable = max(k for k in range(len(table)) if not table.unstable[k])
    out = ROOT / "docs" / "img"
    out.mkdir(exist_ok=True)
    paths = [out / "render_unstable.png", out / "render_probe.png"]
    Image.fromarray(frames[start[unstable] + 3 * render.FRAMES_PER_PROBE // 4 - 1]).save(paths[0], optimize=True)
    Image.fromarray(frames[start[stable] + render.FRAMES_PER_PROBE // 4 - 1]).save(paths[1], optimize=True)
    paths.append(Path(render.save_video(frames, str(out / "render_episode.gif"))))
    return [f"{p.relative_to(ROOT)} ({p.stat().st_size // 1024} kB)" for p in paths]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--episodes", type=int, default=20)
    ap.add_argument("--docs", action="store_true")
    args = ap.parse_args()
    probes, seconds, per_frame = [], [], []
    written = []
    env_class = type(gym.make("PlateRotationAtlas-v0").unwrapped)
    env_class._scene = timed(env_class._scene)  # the scene and its estimate, built once per step
    for hook in ("reset", "step"):
        setattr(render.Renderer, hook, timed(getattr(render.Renderer, hook)))
    for seed in range(args.episodes):
        spent, frames, env = play(seed)
        probes.append(len(env.table()))
        seconds.append(len(frames) / env.metadata["render_fps"])
        per_frame.append(spent / len(frames))
        if args.docs and seed == 1:
            written = docs_images(frames, env.table())
    scene = env._scene()
    n = 10
    t0 = time.process_time()
    for _ in range(n):
        render.probe_frames(scene)
    anim = (time.process_time() - t0) / (n * render.FRAMES_PER_PROBE)
    t0 = time.process_time()
    for _ in range(n):
        render.draw_frame(scene)
    still = (time.process_time() - t0) / n
    load = os.getloadavg()[0]
    lines = [
        "# Rendering: cost per frame and video length (`python experiments/render_video.py`)",
        "",
        f"bayes on PlateRotationAtlas-v0, seeds 0-{args.episodes - 1}, `render_mode=\"rgb_array_list\"`, "
        f"{render.FRAMES_PER_PROBE} frames per probe at render_fps {render.FPS}; one run at load {load:.1f} on a "
        "shared 2-core machine.",
        "",
        "| quantity | median | range |",
        "|---|---|---|",
        f"| probes per episode | {np.median(probes):.0f} | {min(probes)}-{max(probes)} |",
        f"| video length, s | {np.median(seconds):.1f} | {min(seconds):.1f}-{max(seconds):.1f} |",
        "| rendering cost in an episode, CPU ms per frame (scene, estimate, drawing) | "
        f"{1e3 * np.median(per_frame):.1f} | {1e3 * min(per_frame):.1f}-{1e3 * max(per_frame):.1f} |",
        "",
        f"Drawing alone (the last episode's final scene, CPU time): {1e3 * anim:.1f} ms per animation frame "
        f"(the still parts drawn once per probe), {1e3 * still:.1f} ms for a still frame (`rgb_array`).",
    ]
    if written:
        lines += ["", "Written: " + ", ".join(written) + " (seed 1)."]
    text = "\n".join(lines) + "\n"
    (ROOT / "experiments" / "results" / "render_video.md").write_text(text)
    print(text)


if __name__ == "__main__":
    main()
