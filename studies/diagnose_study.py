"""Study: `cart.diagnose` on labelled logs: which effects it names against the truth, and the gap.

    python -m studies.diagnose_study DIR [DIR ...] [--limit N] [--json]

Each DIR holds LOG_FORMAT logs and a ``truth.json`` whose entries may carry ``hidden_effects``
(a list of effect names; empty or absent = effect-free). Prints one row per log (truth, named
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
                    "right": sorted(named[:1]) == sorted(want[:1]),
                    "gap_before": res.gap_before,
                    "gap_after": res.gap_after,
                }
            )
        except CartError as exc:
            rows.append({"log": name, "truth": want, "error": str(exc), "right": False})
    free = [r for r in rows if not r["truth"]]
    summary = {
        "logs": len(rows),
        "right_share": sum(r["right"] for r in rows) / max(len(rows), 1),
        "effect_free_logs": len(free),
        "false_alarms": sum(1 for r in free if r.get("named")),
        "refused": sum(1 for r in rows if "error" in r),
    }
    return {"dir": path, "rows": rows, "summary": summary}


def main(argv=None) -> int:
    """Run the study and print the rows and summaries (or JSON)."""
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("dirs", nargs="+")
    ap.add_argument("--limit", type=int, default=0, help="at most this many logs per directory")
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args(argv)
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
