"""The forward-model registry's builder: ``plate-env build forward-models --within W.json --lomo L.json
--faithful F.json --out F`` writes ``plate_env/data/forward_models.json`` from the measured numbers of
``experiments/forward_models.py``'s ``within`` and ``lomo`` stages (``experiments/results/forward_models_{within,
lomo}.json``) and of ``experiments/faithful_forward.py`` (``experiments/results/faithful_forward.json``: the
faithful rigid-tile atlas's discrepancy): each model's members (shipped atlases) and its fitted discrepancy. The
fitted values live in those result files, not here.

The registry is read as a mapping of model names, so the build record (command, version, commit) goes to a file
beside it, ``F.provenance.json``, and the registry stays byte-identical to the shipped one.
"""

from __future__ import annotations

import json
import math
from collections.abc import Sequence
from importlib import resources
from pathlib import Path

from plate_env.core.files import read_json, write_text_atomic
from plate_env.identify.forward import POINTMASS_JOINT_MEMBERS, pointmass_member_label
from plate_env.identify.inference import fit_discrepancy
from plate_env.surrogate.atlas import load_atlas_file

#: The unknown joint values of the point-mass members (zeta_bending x k_inplane N/m; defined once in
#: :data:`plate_env.identify.forward.POINTMASS_JOINT_MEMBERS`); the nominal one is the shipped dense atlas, the others
#: grid plate_env/data/grids/pointmass_member.json (``--nuisance``).
NUISANCE_MEMBERS = list(POINTMASS_JOINT_MEMBERS)
#: The faithful forward model's atlas: rigid_fast tiles at 1 Hz, 3 and 6 deg (experiments/results/
#: atlas_tilelink_rigid_fast.md); its discrepancy is fitted by experiments/faithful_forward.py.
FAITHFUL = "atlas_tilelink_rigid_fast.npz"
#: The atlases of each model family: the rigid-tile family's member is the faithful 1 Hz atlas (:data:`FAITHFUL`,
#: rigid_fast, within 0.6 % median of the converged rigid_limit it stands for; issue 33), which replaced the 2 Hz
#: rigid_limit atlas (atlas_tilelink_rigid_limit_f2.npz, still shipped) in ``lab`` and ``tilelink/rigid_limit``.
FAMILIES = {
    "pointmass": ["atlas_tilelink_pointmass.npz"] + [f"atlas_tilelink_pointmass_{pointmass_member_label(zb, ki)}.npz"
                                                     for zb, ki in NUISANCE_MEMBERS],
    "rigid": [FAITHFUL],
    "pybullet": ["atlas_pybullet_pybullet.npz"],
}
#: The point-mass atlases along the mass axis (grids plate_env/data/grids/pointmass_m*.json): the nominal member of
#: every point-mass forward model is conditioned on the lab's mass between them.
MASS_ATLASES = ["atlas_tilelink_pointmass_m5.npz", "atlas_tilelink_pointmass_m8.2.npz", "atlas_tilelink_pointmass.npz",
                "atlas_tilelink_pointmass_m23.2.npz", "atlas_tilelink_pointmass_m40.npz"]


def _entry(members: list[list[str]], sigma_eps: float, provenance: dict, nu: float = math.inf,
           offset: tuple[float, float] = (0.0, math.inf)) -> dict:
    out = {"members": [{"atlases": atlases} for atlases in members], "sigma_eps": sigma_eps,
           "pooling": "evidence", "provenance": provenance}
    if math.isfinite(nu):
        out["eps_nu"] = nu
    if offset[0] > 0:
        out["offset_sigma"], out["offset_nu"] = offset
    return out


def registry(within: dict, lomo: dict, faithful: dict) -> dict:
    """The registry from the ``within`` and ``lomo`` stages' numbers and ``faithful_forward``'s (JSON documents).
    Pure but for checking that every member's atlas ships (ValueError naming one that does not)."""
    shipped = resources.files("plate_env") / "data"
    masses = [f for f in MASS_ATLASES if (shipped / f).is_file()]

    def self_discrepancy(fam: str) -> tuple[float, float]:
        import numpy as np

        eps, sd = (np.array(lomo["cross"][f"{fam}->{fam}"][k]) for k in ("eps", "sd"))
        return fit_discrepancy(eps, sd)

    cite = "experiments/results/forward_models_{}.md (python experiments/forward_models.py {})"
    rigid, pyb = self_discrepancy("rigid"), self_discrepancy("pybullet")
    out = {
        "tilelink/pointmass": _entry([masses], within["sigma_eps"], {"sigma_eps": cite.format("within", "within")},
                                     within.get("eps_nu", math.inf)),
        "tilelink/rigid_limit": _entry([FAMILIES["rigid"]], rigid[1],
                                       {"sigma_eps": "held-out rigid_limit sweeps through its atlas, "
                                                     + cite.format("lomo", "lomo")}, rigid[0]),
        "pybullet/pybullet": _entry([FAMILIES["pybullet"]], pyb[1],
                                    {"sigma_eps": "held-out PyBullet sweeps through its atlas, "
                                                  + cite.format("lomo", "lomo")}, pyb[0]),
        "lab": _entry([masses] + [[f] for f in FAMILIES["pointmass"][1:] + FAMILIES["rigid"]
                                   + FAMILIES["pybullet"]],
                      lomo["lab"]["sigma_eps"],
                      {"sigma_eps": "offset between models and the objects' scatter, from every model's data "
                                    "through every other model (plate_env.inference.family_discrepancy), "
                                    + cite.format("lomo", "lomo"),
                       "members": "point mass (nominal along the mass axis, 8 nuisance members), rigid tiles, "
                                  "PyBullet sheet"},
                      lomo["lab"]["eps_nu"], (lomo["lab"]["offset_sigma"], lomo["lab"]["offset_nu"])),
        "tilelink/rigid_fast": _entry([[FAITHFUL]], faithful["sigma_eps"],
                                      {"sigma_eps": "the converged rigid_limit's 20 sweeps through the faithful "
                                                    "atlas, experiments/results/faithful_forward.md (python "
                                                    "experiments/faithful_forward.py)"}, faithful["eps_nu"]),
    }
    for entry in out.values():
        for m in entry["members"]:
            for f in m["atlases"]:
                try:
                    load_atlas_file(f)
                except FileNotFoundError:
                    raise ValueError(f"forward model member {f!r} is not shipped (build it: plate-env build atlas "
                                     "...)") from None
    return out


def _read(path: str | Path, stage: str) -> dict:
    try:
        return read_json(path, f"{stage} results")
    except ValueError as exc:
        script = "faithful_forward.py" if stage == "faithful" else f"forward_models.py {stage}"
        raise ValueError(f"{exc} (written by python experiments/{script})") from None


def build_forward_models(within: str | Path, lomo: str | Path, faithful: str | Path, out: str | Path,
                         record: dict) -> dict:
    """Write the registry from the stages' result files to ``out`` and the build record, with the inputs' paths, to
    ``out`` + ``.provenance.json``; returns the registry. Nothing is written when an input is missing or bad."""
    reg = registry(_read(within, "within"), _read(lomo, "lomo"), _read(faithful, "faithful"))
    write_text_atomic(out, json.dumps(reg, indent=1) + "\n", "--out")
    record = {**record, "artifact": "forward-models", "inputs": {"within": str(within), "lomo": str(lomo),
                                                                 "faithful": str(faithful)}}
    write_text_atomic(f"{out}.provenance.json", json.dumps(record, indent=1) + "\n", "build record")
    return reg


__all__: Sequence[str] = ("FAITHFUL", "FAMILIES", "MASS_ATLASES", "NUISANCE_MEMBERS", "build_forward_models",
                          "registry")
