"""Study: `cart.diagnose` on labelled logs: which effects it names against the truth, and the gap.

    python -m studies.diagnose_study DIR [DIR ...] [--limit N] [--json]
    python -m studies.diagnose_study --write-scenarios DIR [--seeds 8] [--seed0 9000]

Each DIR holds LOG_FORMAT logs and a ``truth.json`` whose entries may carry ``hidden_effects``
(a list of effect names; empty or absent = effect-free). ``--write-scenarios DIR`` first writes
labelled logs of the hidden-effect test bed into DIR: per seed, effect-free logs with a recording
defect (multi-rate tables ``held_pose`` and ``mocap_rows``, a 10 s ``gap``, a Unix ``time_offset``,
a ``wrench_in_cart_frame``, which must be refused) and a log with two hidden effects.

Prints one row per log (truth, named
effects, gap before and after) and, per directory, the share of logs answered right and the
number of false alarms (effects named on effect-free logs).
"""

from __future__ import annotations

import argparse
import glob
import json
import os
import sys

from cart.diagnose import diagnose
from cart.errors import CartError
from cart.jsonout import dumps_strict
from cart.logs import read_log


def _truth_names(entry: dict[str, object]) -> list[str]:
    names = []
    for e in entry.get("hidden_effects", []) or []:
        names.append(e if isinstance(e, str) else str(e.get("name")))
    return names


def study_dir(path: str, limit: int = 0, progress: bool = False) -> dict[str, object]:
    """Return rows and a summary of `diagnose` over one directory of labelled logs (``progress``: a bar on stderr)."""
    from wholebody.progress import progress_bar

    truth = json.load(open(os.path.join(path, "truth.json")))
    files = sorted(glob.glob(os.path.join(path, "*.csv*")))
    files = [f for f in files if os.path.basename(f).split(".")[0] in truth]
    if limit:
        files = files[:limit]
    rows = []
    for f in progress_bar(files, desc=f"diagnose {os.path.basename(path)}", unit="log", enabled=progress):
        name = os.path.basename(f).split(".")[0]
        want = _truth_names(truth[name])
        try:
            res = diagnose(read_log(f))
            named = [e.name for e in res.effects]
            rows.append(
                {
                    "log": name,
                    "truth": want,
                    "named": named,
                    "right": sorted(named[:1]) == sorted(want[:1]) and not truth[name].get("refuse"),
                    "all_named": set(want) <= set(named),
                    "extra": len(set(named) - set(want)),
                    "gap_before": res.gap_before,
                    "gap_after": res.gap_after,
                }
            )
        except CartError as exc:
            refuse = bool(truth[name].get("refuse"))
            rows.append({"log": name, "truth": want, "error": str(exc), "right": refuse})
    free = [r for r in rows if not r["truth"]]
    summary = {
        "logs": len(rows),
        "right_share": sum(r["right"] for r in rows) / max(len(rows), 1),
        "effect_free_logs": len(free),
        "false_alarms": sum(1 for r in free if r.get("named")),
        "refused": sum(1 for r in rows if "error" in r),
        "multi_effect_logs": sum(1 for r in rows if len(r["truth"]) > 1),
        "multi_effect_all_named": sum(1 for r in rows if len(r["truth"]) > 1 and r.get("all_named")),
        "multi_effect_extra_names": sum(r.get("extra", 0) for r in rows if len(r["truth"]) > 1),
    }
    return {"dir": path, "rows": rows, "summary": summary}


#: pairs of effects hidden together in the two-effect scenarios (cycled over the seeds)
PAIRS = (
    ("coulomb_friction", "wrench_bias"),
    ("payload_change", "floor_slope"),
    ("time_delay", "coulomb_friction"),
    ("wrench_bias", "floor_slope"),
    ("floor_slope", "coulomb_friction"),
    ("payload_change", "time_delay"),
    ("coulomb_friction", "payload_change"),
    ("wrench_bias", "time_delay"),
)


def write_scenarios(out: str, seeds: int = 8, seed0: int = 9000) -> dict[str, dict]:
    """Write the scenario logs (see the module doc) and their ``truth.json`` into ``out``; return the truth."""
    import numpy as np

    from cart.logs import write_log
    from studies.testbeds.hidden_effects import (
        defective_log,
        multirate_log,
        random_case,
        random_cart,
        random_effect,
        simulate_hidden,
    )

    os.makedirs(out, exist_ok=True)
    truth: dict[str, dict] = {}
    for k in range(seeds):
        rng = np.random.default_rng(seed0 + k)
        for merging in ("held_pose", "mocap_rows"):
            log, _ = multirate_log(rng, merging)
            write_log(os.path.join(out, f"{merging}{k:02d}.csv"), log)
            truth[f"{merging}{k:02d}"] = {"hidden_effects": [], "defect": merging}
        base = random_case(None, rng, duration=40.0).measured
        for defect in ("gap", "time_offset", "wrench_in_cart_frame"):
            write_log(os.path.join(out, f"{defect}{k:02d}.csv"), defective_log(base, defect, rng))
            truth[f"{defect}{k:02d}"] = {"hidden_effects": [], "defect": defect, "refuse": defect.startswith("wrench")}
        params = random_cart(rng)
        pair = PAIRS[k % len(PAIRS)]
        effects = tuple(random_effect(name, rng, params, 40.0) for name in pair)
        hl = simulate_hidden(params, effects, duration=40.0, rate=100.0, jitter=0.1, rng=rng)
        write_log(os.path.join(out, f"two{k:02d}.csv"), hl.measured)
        truth[f"two{k:02d}"] = {"hidden_effects": list(pair)}
    with open(os.path.join(out, "truth.json"), "w") as fh:
        json.dump(truth, fh, indent=1)
    return truth


def main(argv=None) -> int:
    """Run the study and print the rows and summaries (or JSON)."""
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("dirs", nargs="*")
    ap.add_argument("--limit", type=int, default=0, help="at most this many logs per directory")
    ap.add_argument("--json", action="store_true")
    ap.add_argument("--write-scenarios", metavar="DIR", help="write the scenario logs into DIR first, then study it")
    ap.add_argument("--seeds", type=int, default=8, help="scenario seeds (default 8)")
    ap.add_argument("--seed0", type=int, default=9000, help="first scenario seed (default 9000)")
    args = ap.parse_args(argv)
    if args.write_scenarios:
        write_scenarios(args.write_scenarios, args.seeds, args.seed0)
        args.dirs = list(args.dirs) + [args.write_scenarios]
    from wholebody.progress import show_progress

    results = [study_dir(d, args.limit, progress=show_progress(args.json)) for d in args.dirs]
    if args.json:
        print(dumps_strict(results))
        return 0
    for res in results:
        print(f"== {res['dir']}")
        for r in res["rows"]:
            what = (
                r.get("error") or f"named {r['named'] or ['none']}, gap {r['gap_before']:.4f} -> {r['gap_after']:.4f} m"
            )
            print(f"{r['log']:12s} truth {r['truth'] or ['none']}: {what}")
        print(json.dumps(res["summary"]))
    return 0


if __name__ == "__main__":
    sys.exit(main())
