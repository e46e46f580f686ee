"""The benchmark (plate_env.benchmark, plate-env bench): the plug-in protocol, budgets read from one run, resumable
records, determinism, summaries and the leaderboard. Fast: the atlas suite, a few objects."""

from __future__ import annotations

import functools
import json
import math
import re
from pathlib import Path

import numpy as np
import pytest

from plate_env import bench as benchmark
from plate_env.bench import runner
from plate_env.bench.suites import load_suite
from plate_env.cli import main
from plate_env.env.episode import estimate_of, run_episode
from plate_env.env.protocol import Agent, Probe
from plate_env_agents import load_agent

ROOT = Path(__file__).resolve().parents[1]
EXAMPLE = ROOT / "examples" / "sweep_agent.py"
SUITE = load_suite("atlas-v0")


class Fixed(Agent):
    """Probes at fixed frequencies with 1 s windows, then stops."""

    name = "fixed"

    def __init__(self, freqs=(14.0, 18.0, 22.0, 26.0, 30.0), amp=3.0, window=1.0) -> None:
        self.freqs, self.amp, self.window = tuple(freqs), amp, window

    def next_probe(self, history, obs=None):
        k = len(history)
        return Probe(self.freqs[k], self.amp, self.window) if k < len(self.freqs) else None


def test_the_docs_example_agent_is_the_file_the_tests_run():
    page = (ROOT / "docs" / "benchmark.md").read_text()  # the README points there ("Write your own agent")
    block = re.search(r"```python\n(# examples/sweep_agent\.py\n.*?)```", page, re.S)
    assert block, "docs/benchmark.md shows examples/sweep_agent.py in a python block starting with its path"
    code = EXAMPLE.read_text()
    body = code[code.index("import numpy"):]
    assert block.group(1).split("\n", 1)[1] == body
    assert len(body.strip().splitlines()) <= 25


def test_example_agent_through_the_command_line(capsys):
    rc = main(["bench", "--suite", "atlas-v0", "--agent", f"{EXAMPLE}:SweepAgent", "--limit", "3", "--json",
               "--no-cache"])
    out = json.loads(capsys.readouterr().out)
    assert rc == 0 and out["suite"] == "atlas-v0" and out["budgets_s"] == [10.0, 20.0, 40.0]
    (agent,) = out["agents"]
    assert agent["label"].endswith("sweep_agent.py:SweepAgent") and agent["n"] == 3 and agent["limit"] == 3
    top = agent["budgets"][-1]
    assert top["no_estimate"]["value"] == 0.0 and 0.0 <= top["median_error"]["value"] < 0.2
    assert top["probes_mean"] >= 3  # at least three stable probes before it can see the peak pass


@pytest.mark.parametrize("spec, message", [
    ("examples/nope.py:A", "no such file"),
    (f"{EXAMPLE}:Missing", "no class 'Missing'.*SweepAgent"),
    (f"{EXAMPLE}", "file.py:ClassName"),
    ("grid:n", "key=value"),
    ("gridd", "unknown agent"),
    ("sb3:nowhere.zip", "no SB3 model"),
])
def test_bad_agent_specs_are_refused_before_any_episode(spec, message, capsys):
    assert main(["bench", "--suite", "atlas-v0", "--agent", spec, "--no-cache"]) == 2
    err = capsys.readouterr().err
    assert re.search(message, err) and err.count("\n") == 1


def test_an_object_without_the_protocol_is_refused_naming_what_is_missing(tmp_path):
    path = tmp_path / "bad.py"
    path.write_text("class NotAnAgent:\n    name = 'x'\n    def reset(self, context, rng):\n        pass\n")
    with pytest.raises(ValueError, match=r"next_probe"):
        load_agent(f"{path}:NotAnAgent")


def test_an_agent_answer_the_env_refuses_names_the_agent():
    env = SUITE.make_env()
    with pytest.raises(ValueError, match="agent 'fixed'.*A_p = 5"):
        run_episode(env, Fixed(amp=5.0), seed=0)
    env.close()


def test_cli_bench_refuses_bad_budgets_and_suites(capsys):
    assert main(["bench", "--suite", "atlas-v0", "--agent", "grid", "--budgets", "10,80", "--no-cache"]) == 2
    assert "(0, 40]" in capsys.readouterr().err
    assert main(["bench", "--suite", "nope-v0", "--agent", "grid", "--no-cache"]) == 2
    assert "unknown suite" in capsys.readouterr().err


def test_every_budget_is_read_from_one_run_as_separate_runs_would_give():
    """The estimate at budget B from the long run equals that of a separate run cut at B (a deterministic agent
    plays the same first probes), and an agent that stopped early keeps its final estimate at larger budgets."""
    agent = load_agent("coarse_to_fine")
    run = benchmark.evaluate(agent, SUITE, limit=2)
    env = SUITE.make_env()
    for ep, obj in zip(run.episodes, SUITE.objects, strict=False):
        cum = np.cumsum(ep.probe_sim_s)
        assert ep.n_at(cum[0] * 0.99) == 0 and not ep.estimate_at(cum[0] * 0.99).ok
        for budget in (cum[2], cum[2] + 0.01, 0.5 * (cum[3] + cum[4])):
            short = run_episode(env, load_agent("coarse_to_fine"), seed=obj.seed, options=obj.reset_options(),
                                max_sim_s=budget)
            k = int(np.sum(np.cumsum(short.probe_sim_s) <= budget))
            cut = short.probes.subset(np.arange(len(short.probes)) < k)
            assert k == ep.n_at(budget)
            assert estimate_of(env, cut, "atlas").omega_n == ep.estimate_at(budget).omega_n
        assert cum[-1] < SUITE.max_budget_s  # coarse_to_fine stopped on its own (12 probes) ...
        final = ep.prefix[-1]
        assert ep.estimate_at(SUITE.max_budget_s).omega_n == final.omega_n  # ... and keeps its last estimate
    env.close()


def test_episodes_stop_at_the_largest_budget():
    # 2 s windows: a stable probe costs 2.7 simulated s, so the budget ends the episode before the suite's 30 probes
    # (with 1 s windows, unstable probes end early enough on some objects for 30 probes to fit in 40 s)
    run = benchmark.evaluate(load_agent("grid:n=30,method=atlas,measure_s=2.0"), SUITE, limit=2)
    for ep in run.episodes:
        cum = np.cumsum(ep.probe_sim_s)
        assert len(cum) < SUITE.env_kwargs["max_probes"]  # cut by the budget, not by the probe limit
        assert cum[-2] < SUITE.max_budget_s <= cum[-1]  # the probe that crosses the budget is the last one
        assert ep.n_at(SUITE.max_budget_s) == len(cum) - 1


def test_records_resume_and_name_the_agent(tmp_path):
    cache = tmp_path / "bench.jsonl"
    a = benchmark.evaluate(Fixed(), SUITE, limit=3, cache=cache)
    assert len(cache.read_text().splitlines()) == 3
    b = benchmark.evaluate(Fixed(), SUITE, limit=4, cache=cache)
    assert len(cache.read_text().splitlines()) == 4  # only the fourth episode was played
    assert [e.wall_s for e in b.episodes[:3]] == [e.wall_s for e in a.episodes]  # read back, not replayed
    benchmark.evaluate(Fixed(freqs=(15.0, 19.0, 23.0)), SUITE, limit=2, cache=cache)
    assert len(cache.read_text().splitlines()) == 6  # other options: another agent, its own records
    with open(cache, "a") as fh:
        fh.write('{"key": "torn')  # an interrupted write
    c = benchmark.evaluate(Fixed(), SUITE, limit=4, cache=cache)
    assert _outcome(c) == _outcome(b)


def _outcome(run):
    return [(e.index, e.probe_sim_s, e.probes, [runner._est_record(x) for x in e.prefix]) for e in run.episodes]


def test_same_records_in_process_and_in_a_process_pool():
    spec = "coarse_to_fine:n_coarse=4,n_fine=3"
    here = benchmark.evaluate(load_agent(spec), SUITE, limit=4)
    pool = benchmark.evaluate(functools.partial(load_agent, spec), SUITE, limit=4, executor="pool:2", chunk=1)
    assert _outcome(here) == _outcome(pool)


def test_summary_agrees_with_scoring_and_the_board_ranks_by_area():
    runs = [benchmark.evaluate(load_agent(s), SUITE, limit=6, label=s) for s in ("coarse_to_fine", "grid")]
    b = benchmark.board(runs)
    by = {s.label: s for s in b["summaries"]}
    grid = by["grid"]
    errs = [e.estimate_at(20.0).relative_error(e.omega_n_true) for e in runs[1].episodes]
    assert grid.at(20.0).scores.median_error.value == pytest.approx(float(np.median(errs)))
    assert grid.at(10.0).scores.no_estimate.value == 1.0  # the paper's fit needs more of its sweep than 10 s
    assert b["leader"] == min(by.values(), key=lambda s: s.area.value).label == "coarse_to_fine"
    curve = np.minimum(np.array(by["coarse_to_fine"].curve_median), 1.0)
    assert by["coarse_to_fine"].area.value == pytest.approx(float(np.mean(0.5 * (curve[1:] + curve[:-1]))))
    text = benchmark.leaderboard_markdown(b["summaries"], b["paired"], b["leader"])
    assert text.index("| 1 | coarse_to_fine") < text.index("| 2 | grid")
    assert "Paired differences against the leader, `coarse_to_fine`" in text
    self_diff = benchmark.compare(runs[0], runs[0], 20.0)
    assert (self_diff.value, self_diff.lo, self_diff.hi) == (0.0, 0.0, 0.0)
    d = json.loads(json.dumps(benchmark.board_to_dict(b)))
    assert d["leader"] == "coarse_to_fine" and math.isfinite(d["agents"][0]["area"]["value"])


def test_bench_plot_is_written_after_the_table(tmp_path, capsys):
    plot = tmp_path / "curves.png"
    md = tmp_path / "board.md"
    assert main(["bench", "--suite", "atlas-v0", "--agent", "coarse_to_fine", "ppo", "--limit", "2", "--plot",
                 str(plot), "--markdown", str(md), "--cache", str(tmp_path / "c.jsonl"), "--no-progress"]) == 0
    out = capsys.readouterr().out
    assert out.index("| rank |") < out.index(f"plot: {plot}") and plot.stat().st_size > 1000
    assert md.read_text() in out


def test_ctrl_c_keeps_the_finished_episodes_and_a_rerun_resumes(tmp_path, monkeypatch, capsys):
    cache = tmp_path / "c.jsonl"
    real = runner.play
    played = []

    def interrupted(*args, **kw):
        if len(played) == 2:
            raise KeyboardInterrupt
        played.append(1)
        return real(*args, **kw)

    monkeypatch.setattr(runner, "play", interrupted)
    argv = ["bench", "--suite", "atlas-v0", "--agent", "coarse_to_fine", "--limit", "4", "--cache", str(cache),
            "--no-progress", "--chunk", "1"]
    assert main(argv) == 130
    err = capsys.readouterr().err
    assert "after 2 episodes" in err and str(cache) in err and len(cache.read_text().splitlines()) == 2
    monkeypatch.setattr(runner, "play", real)
    assert main(argv) == 0 and len(cache.read_text().splitlines()) == 4


@pytest.mark.slow
def test_pybullet_suite_plays_an_episode():
    run = benchmark.evaluate(load_agent("coarse_to_fine:n_coarse=4,n_fine=2,width_hz=2.0"), "pybullet-v0", limit=1)
    (ep,) = run.episodes
    assert 1 <= len(ep.probe_sim_s) <= 6 and sum(ep.probe_sim_s) > 0
    assert len(ep.prefix) == len(ep.probe_sim_s)


def test_the_misspecification_track_is_one_bench_invocation_of_agents_against_suites(capsys):
    """Issue 33: ``--suite`` takes several suites and ``NAME:forward=MODEL`` reads an agent's episodes through another
    physics' forward model. On the point mass's episodes the point-mass reading is the own one (the same numbers);
    on the rigid tiles' episodes it is refused (the predictive check: no estimate), while the own reading answers."""
    argv = ["bench", "--suite", "misspec_pointmass-v0", "misspec_faithful-v0", "--agent", "grid:method=atlas",
            "grid:method=atlas,forward=tilelink/pointmass", "--limit", "4", "--no-cache", "--json",
            "--executor", "inprocess"]
    assert main(argv) == 0
    doc = json.loads(capsys.readouterr().out)
    assert [s["suite"] for s in doc["suites"]] == ["misspec_pointmass-v0", "misspec_faithful-v0"]
    cell = {(s["suite"], a["label"]): a["budgets"][-1] for s in doc["suites"] for a in s["agents"]}
    own, pm = "grid:method=atlas", "grid:method=atlas,forward=tilelink/pointmass"
    assert cell["misspec_pointmass-v0", pm]["median_error"] == cell["misspec_pointmass-v0", own]["median_error"]
    assert cell["misspec_pointmass-v0", pm]["no_estimate"]["value"] == 0.0
    assert cell["misspec_faithful-v0", own]["no_estimate"]["value"] == 0.0
    assert cell["misspec_faithful-v0", own]["median_error"]["value"] < 0.05
    assert cell["misspec_faithful-v0", pm]["no_estimate"]["value"] == 1.0
    # the text form is the matrix, then each suite's leaderboard
    assert main(argv[:-3] + ["--no-progress", "--executor", "inprocess"]) == 0
    text = capsys.readouterr().out
    assert "| agent | `misspec_pointmass-v0` | `misspec_faithful-v0` |" in text
    assert text.count("## misspec_") == 2


@pytest.mark.parametrize("argv, needle", [
    (["--suite", "atlas-v0", "atlas-v0", "--agent", "grid"], "each suite once"),
    (["--suite", "atlas-v0", "faithful-v0", "--agent", "grid", "--cache", "x.jsonl"], "--cache names one suite"),
    (["--suite", "atlas-v0", "faithful-v0", "--agent", "grid", "--plot", "x.png"], "--plot draws one suite"),
    (["--agent", "grid:forward=lab"], "method 'lorentz', which reads no forward model"),
    (["--agent", "bayes:forward=nope"], "no such forward model"),
])
def test_misspecification_options_that_cannot_work_are_refused_before_any_episode(argv, needle, capsys):
    assert main(["bench", *argv, "--limit", "1", "--no-cache"]) == 2
    assert needle in capsys.readouterr().err


def test_an_agent_forward_option_names_the_model_its_estimate_uses_and_its_record():
    from plate_env.bench.fingerprint import agent_fingerprint

    plain, lab = load_agent("grid:method=atlas"), load_agent("grid:method=atlas,forward=lab")
    assert agent_fingerprint(plain) != agent_fingerprint(lab)
    assert agent_fingerprint(load_agent("bayes")) != agent_fingerprint(load_agent("bayes:forward=lab"))
    env = load_suite("misspec_faithful-v0").make_env()
    res = run_episode(env, lab, seed=16_000, options=None)
    assert res.estimate.ok and res.estimate.omega_n > 0
    assert lab.estimate_model().name == "lab" and plain.estimate_model() is None


def test_the_regenerate_line_names_a_suite_file_as_it_was_given(tmp_path, capsys):
    """Issue 38 item 7: a suite given as a file was printed by its name, a command that then failed (unknown suite)."""
    from plate_env.bench.suites import suite_dir

    path = tmp_path / "atlas-v0.json"
    path.write_text((suite_dir() / "atlas-v0.json").read_text())
    assert main(["bench", "--suite", str(path), "--agent", "grid:method=atlas", "--limit", "1", "--no-cache",
                 "--no-progress", "--executor", "inprocess"]) == 0
    assert f"--suite {path} --agent" in capsys.readouterr().out
