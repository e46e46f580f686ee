"""Run an agent for one episode of PlateRotation-v0 and score its estimate (the loop lives in the library core,
:mod:`plate_env.episode`)."""

from __future__ import annotations

from plate_env.episode import EpisodeResult, run_episode

__all__ = ["EpisodeResult", "run_episode"]
