"""Study: `cart.identify` (whole-log least squares) on labelled logs: bias and coverage.

    python -m studies.estimation_study DIR [DIR ...] [--json]

Each DIR holds LOG_FORMAT logs and a ``truth.json`` keyed by log name (the
format of ``studies.testbeds.rigid_sim.generate`` and ``mujoco_cart.generate``).
Prints one row per log (truth, estimate +- std, error in stds) and, per
directory, the mean relative mass error and the share of truths within 1, 2
and 3 reported std for mass, CoM (dx, dy) and inertia.
"""

from __future__ import annotations

import argparse
import glob
import json
import os
import sys

import numpy as np

from cart.identify import identify
from cart.logs import read_log
from cart.jsonout import dumps_strict


def study_dir(path: str, progress: bool = False) -> dict[str, object]:
    """Return the rows and the coverage summary of one directory of labelled logs (``progress``: a bar on stderr)."""
    from wholebody.progress import progress_bar

    truth = json.load(open(os.path.join(path, "truth.json")))
    rows: list[dict[str, object]] = []
    files = sorted(glob.glob(os.path.join(path, "*.csv*")))
    for f in progress_bar(files, desc=f"estimate {os.path.basename(path)}", unit="log", enabled=progress):
        name = os.path.basename(f).split(".")[0]
        if name not in truth:
            continue
        tr = truth[name]
        try:
            res = identify(read_log(f))
        except Exception as exc:  # a study reports every log, refused ones included
            rows.append({"log": name, "error": f"{type(exc).__name__}: {exc}"})
            continue
        p, s = res.params, res.std
        est = [p.m, p.dx, p.dy, p.I]
        std = [s["mass"], s["com"][0], s["com"][1], s["inertia"]]
        tru = [tr["m"], tr["dx"], tr["dy"], tr["I_about_com"]]
        z = [(e - t) / max(d, 1e-300) for e, t, d in zip(est, tru, std)]
        rows.append(
            {
                "log": name,
                "truth": tru,
                "estimate": est,
                "std": std,
                "z": z,
                "model_fits": res.model_fits,
                "warnings": list(res.warnings),
            }
        )
    ok = [r for r in rows if "z" in r]
    z = np.abs(np.array([r["z"] for r in ok])) if ok else np.zeros((0, 4))
    rel = np.array([r["estimate"][0] / r["truth"][0] - 1.0 for r in ok]) if ok else np.zeros(0)
    summary = {
        "logs": len(rows),
        "refused": len(rows) - len(ok),
        "mass_rel_error_mean": float(rel.mean()) if len(rel) else None,
        "mass_rel_error_max": float(np.abs(rel).max()) if len(rel) else None,
        "mass_abs_error_max_kg": float(max(abs(r["estimate"][0] - r["truth"][0]) for r in ok)) if ok else None,
        "com_abs_error_max_m": float(
            max(max(abs(r["estimate"][1] - r["truth"][1]), abs(r["estimate"][2] - r["truth"][2])) for r in ok)
        )
        if ok
        else None,
        "model_fits_share": float(np.mean([r["model_fits"] for r in ok])) if ok else None,
        "coverage": {
            f"{k}std": {n: float(np.mean(z[:, i] < k)) for i, n in enumerate(("m", "dx", "dy", "I"))} for k in (1, 2, 3)
        },
    }
    return {"dir": path, "rows": rows, "summary": summary}


def main(argv=None) -> int:
    """Run the study over the directories and print the tables (or JSON)."""
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("dirs", nargs="+")
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args(argv)
    from wholebody.progress import show_progress

    results = [study_dir(d, progress=show_progress(args.json)) for d in args.dirs]
    if args.json:
        print(dumps_strict(results))
        return 0
    for res in results:
        print(f"== {res['dir']}")
        print(
            f"{'log':10s} {'m true':>8s} {'m est +- std':>18s} {'z_m':>6s} {'dx true':>8s} {'dx est +- std':>17s} "
            f"{'z_dx':>6s} {'I true':>7s} {'I est +- std':>16s} {'z_I':>6s} fits"
        )
        for r in res["rows"]:
            if "error" in r:
                print(f"{r['log']:10s} refused: {r['error']}")
                continue
            t, e, s, z = r["truth"], r["estimate"], r["std"], r["z"]
            print(
                f"{r['log']:10s} {t[0]:8.2f} {e[0]:9.2f} +- {s[0]:5.2f} {z[0]:6.1f} {t[1]:8.3f} {e[1]:8.3f} +- "
                f"{s[1]:5.3f} {z[1]:6.1f} {t[3]:7.2f} {e[3]:7.2f} +- {s[3]:5.2f} {z[3]:6.1f} {r['model_fits']}"
            )
        sm = res["summary"]
        print(json.dumps(sm, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
