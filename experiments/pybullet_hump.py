"""Does the PyBullet sheet show a first hump if its friction or contact margin changes? (issue 27, item 4)

    python experiments/pybullet_hump.py [--variants kinetic,margin1.5] [--objects 10,33]

A screening on the objects of Fig. 7 (10pi and 33pi, alpha 36.9 deg, A_p 3 deg, 12-34 Hz in 2 Hz steps, the
pybullet atlas's 0.3 s + 0.6 s windows, placement 0 of ``validate_paper.py`` so the baseline is that script's
cached sweep). Variants:

* ``kinetic``: PyBullet has one Coulomb coefficient and the sheet uses mu_s = tan(alpha); the paper's slipping
  nodes feel mu_k = 0.53 mu_s. The sheet is run with alpha' = atan(0.53 tan alpha) (21.7 deg for 36.9 deg):
  the whole contact at the kinetic level;
* ``marginX``: soft-body collision margin X mm (default 0.5 mm);
* ``thickX``: sheet thickness X mm (default 2 mm); ``meshN``: N points per layer (default 91). The stiffness
  calibration belongs to the default mesh, so these change omega_n too: a screening for the hump's existence only;
* ``static``: the same alpha as the baseline (a second run of the baseline's probes would be bit-identical;
  only listed to show the baseline).

The bar (issue 27): a first hump that a Lorentzian fits in >= 6 of 8 objects over 5-33pi. With two objects this
is a screening: a variant that gives no fit on both is a measured negative. Caches in
experiments/cache/pybullet_hump.jsonl; writes experiments/results/pybullet_hump.{json,md}.
"""

from __future__ import annotations

import argparse
import json
import math
from dataclasses import replace
from pathlib import Path

import common
from common import kept

from plate_env.cli import CliError
from plate_env.cli import parse_freqs as cli_parse_freqs
from plate_env.physics.pybullet_sheet.scene import SheetConfig
from plate_env.run.executor import BackendSpec
from plate_env.run.sweeps import backend_tag, load_cache, run_cached, spec_key

SCRIPT = "experiments/pybullet_hump.py"
BETA = 0.53


def variant(name: str) -> tuple[BackendSpec, float]:
    """(backend, factor on tan(alpha)) of a variant name."""
    if name == "static":
        return BackendSpec.of("pybullet", n_workers=1), 1.0
    if name == "kinetic":
        return BackendSpec.of("pybullet", n_workers=1), BETA
    if name.startswith("margin"):
        mm = float(name[len("margin"):])
        if not 0.0 < mm <= 10.0:
            raise ValueError(f"margin {mm} mm must lie in (0, 10]")
        return BackendSpec.of("pybullet", n_workers=1, config=SheetConfig(margin=mm * 1e-3)), 1.0
    if name.startswith("thick"):
        mm = float(name[len("thick"):])
        if not 0.0 < mm <= 20.0:
            raise ValueError(f"thickness {mm} mm must lie in (0, 20]")
        return BackendSpec.of("pybullet", n_workers=1, thickness=mm * 1e-3), 1.0
    if name.startswith("mesh"):
        n = int(name[len("mesh"):])
        return BackendSpec.of("pybullet", n_workers=1, n_layer=n), 1.0
    raise ValueError(f"unknown variant {name!r}: static, kinetic, margin<mm>, thick<mm> or mesh<points per layer>")


def parse_freqs(text: str | None) -> tuple[float, ...] | None:
    """``LO:HI:STEP`` (Hz) -> the frequencies (the command line's :func:`plate_env.cli.parse_freqs`, its range and
    probe-count checks), or None for the table's own."""
    if not text:
        return None
    if text.count(":") != 2:
        raise ValueError(f"--freqs {text!r} must be LO:HI:STEP in Hz, e.g. 12:24:1")
    try:
        return tuple(float(f) for f in cli_parse_freqs(text))
    except CliError as e:
        raise ValueError(str(e)) from None


def copy_records(physics: BackendSpec, specs: list, source: Path, cache: Path) -> int:
    """Append to ``cache`` the records of ``specs`` that ``source`` (the table's cache, only read) already holds
    and ``cache`` lacks, so a finer sweep re-runs none of the table's probes. Returns how many were copied."""
    tag = backend_tag(physics)
    have, table = load_cache(cache), load_cache(source)
    new = [table[k] for k in (spec_key(tag, s) for s in specs) if k in table and k not in have]
    if new:
        with cache.open("a") as fh:
            fh.writelines(json.dumps(r) + "\n" for r in new)
    return len(new)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--variants", default="static,kinetic,margin1.5")
    ap.add_argument("--objects", default="10,33", help="omega_n values (pi rad/s) at alpha 36.9 deg")
    ap.add_argument("--cache-dir", default="experiments/cache")
    ap.add_argument("--out-dir", default="experiments/results")
    ap.add_argument("--no-simulate", action="store_true")
    ap.add_argument("--freqs", default=None, help="LO:HI:STEP Hz on the table's 1 Hz grid (default: the table's "
                    "12-34 Hz in 2 Hz steps); results go to pybullet_hump_LO-HI-STEP.{json,md}")
    ap.add_argument("--kept", action="store_true", help="fit with slipped probes' pre-slip omega_B kept (the reading "
                    "of experiments/kept_12deg.py); results go to ..._kept.{json,md}")
    args = ap.parse_args()
    names = [v.strip() for v in args.variants.split(",") if v.strip()]
    for n in names:
        variant(n)  # refuse bad names before any work
    omegas = [float(w) for w in args.objects.split(",")]
    try:
        grid = parse_freqs(args.freqs)
        if grid is not None:
            common.Sweep(10.0, common.CHEESE, 3.0, 1).specs("pybullet", 0, grid)  # refuse a frequency off the grid
    except ValueError as e:
        ap.error(str(e))
    span = "12-34 Hz (2 Hz)" if grid is None else f"{args.freqs.replace(':', '-', 1).replace(':', ' Hz (')} Hz)"
    out = {"command": f"python {SCRIPT} --variants {args.variants} --objects {args.objects}"
                      + (f" --freqs {args.freqs}" if grid else "") + (" --kept" if args.kept else ""), "rows": []}
    md = ["# PyBullet sheet: friction and margin variants against a first hump", "",
          f"Regenerate: `{out['command']}`. 3 deg, alpha 36.9 deg, {span}, 0.3 s + 0.6 s windows, "
          "validate_paper.py's placement 0. Fit: the project's first-hump Lorentzian, f0 inside the fitted probes"
          + (" (slipped probes that measured a period read as stable: `--kept`)." if args.kept else "."),
          "", "| variant | object | fit | f0 [Hz] | b [Hz] | omega_Brmax [deg/s] | R^2 | unstable / probes | "
          "omega_B by f_p (u: unstable) |", "|---|---|---|---|---|---|---|---|---|"]
    for name in names:
        physics, k = variant(name)
        table_cache = common.cache_path(Path(args.cache_dir), "pybullet")
        cache = table_cache if name == "static" and grid is None else Path(args.cache_dir) / "pybullet_hump.jsonl"
        for w in omegas:
            sw = common.Sweep(w, common.CHEESE, 3.0, 1)
            specs = sw.specs("pybullet", 0, grid)
            if k != 1.0:
                a2 = math.atan(k * math.tan(math.radians(common.CHEESE)))
                specs = [replace(s, obj=replace(s.obj, alpha=a2)) for s in specs]
            if args.no_simulate:
                from plate_env.run.sweeps import result_from_record
                done = load_cache(cache)
                tag = backend_tag(physics)
                recs = [done.get(spec_key(tag, s)) for s in specs]
                if not all(recs):
                    md.append(f"| {name} | {w:g}pi | not run | | | | | | |")
                    continue
                res = [result_from_record(s, r) for s, r in zip(specs, recs, strict=True)]
            else:
                if cache != table_cache:
                    copy_records(physics, specs, table_cache, cache)
                res = run_cached(physics, specs, cache, chunk=12, progress=False)
            fit = common.fit_sweep(kept(res) if args.kept else res)
            curve = " ".join(f"{r.spec.motion.freq_hz:g}:{abs(r.omega_b_deg_s):.0f}{'u' if r.unstable else ''}"
                             for r in res)
            n_un = sum(r.unstable for r in res)
            row = {"variant": name, "omega_pi": w, "fit": fit.to_dict(), "unstable": n_un, "probes": len(res),
                   "curve": [[r.spec.motion.freq_hz, r.omega_b_deg_s, r.unstable] for r in res]}
            out["rows"].append(row)
            nums = (f"{fit.f0:.1f} | {fit.b:.1f} | {fit.omega_max:.0f} | {fit.r2:.2f}" if fit.ok
                    else " | | | ")
            md.append(f"| {name} | {w:g}pi | {'ok' if fit.ok else 'no: ' + str(fit.reason)} | {nums} | "
                      f"{n_un}/{len(res)} | {curve} |")
    od = Path(args.out_dir)
    od.mkdir(parents=True, exist_ok=True)
    stem = "pybullet_hump" + ("" if grid is None else "_" + args.freqs.replace(":", "-"))
    stem += "_kept" if args.kept else ""
    (od / f"{stem}.json").write_text(json.dumps(out, indent=1, default=float) + "\n")
    (od / f"{stem}.md").write_text("\n".join(md) + "\n")
    print("\n".join(md))


if __name__ == "__main__":
    main()
