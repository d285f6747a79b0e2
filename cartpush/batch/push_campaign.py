"""Push campaigns: every combination of robots, cart masses and trajectories, one JSON line per run.

``cartpush batch push --robots NAME|PROFILE... --masses KG... --trajectories 1 2 --out RESULTS.jsonl``
runs each combination with `wholebody.push.run_push` (on the kinematic or the MuJoCo plant) on the batch engine's
workers (joblib processes or Ray tasks) and appends one line per run as it finishes::

    {"run": {"robot": ..., "mass": 20.0, "trajectory": 2, "arms": 1, "plant": "kinematic", ...},
     "ok": true, "result": <the push metrics, as `cartpush push --json`>, "seconds": ...}

A rerun with the same ``--out`` skips the runs already done (ok) and retries the failed ones.
"""

from __future__ import annotations

import json
import os
import time
from collections.abc import Iterable, Iterator, Sequence
from dataclasses import asdict, dataclass, replace
from typing import TYPE_CHECKING, Any, cast

from cartpush.batch.engine import (
    ok_records,
    BatchError,
    _check_workers,
    _open_results,
    _progress_bar,
    _results,
    _write_results,
)

if TYPE_CHECKING:
    from wholebody.push.config import PlantName

#: Plants a campaign can run on.
PLANTS = ("kinematic", "mujoco")


@dataclass(frozen=True)
class PushRun:
    """One run of a campaign: robot (name or absolute profile path), true cart mass (kg), trajectory, arms, plant."""

    robot: str
    mass: float
    trajectory: int
    arms: int = 1
    plant: PlantName = "kinematic"
    duration: float = 30.0
    seed: int = 0

    def key(self) -> str:
        """Return the run's canonical key (sorted JSON of its fields)."""
        return json.dumps(asdict(self), sort_keys=True)


def _robot_ref(robot: str) -> str:
    """Return a robot name as is, a profile path made absolute (workers may run elsewhere in the tree)."""
    from robots.registry import is_profile_path

    return os.path.abspath(robot) if is_profile_path(robot) else robot


def campaign(
    robots: Sequence[str],
    masses: Sequence[float],
    trajectories: Sequence[int],
    arms: int = 1,
    plant: str = "kinematic",
    duration: float = 30.0,
    seed: int = 0,
) -> list[PushRun]:
    """Return every combination of robots x masses x trajectories (in that order), each checked up front.

    Each robot's profile is read (a bad name or file raises here, before any run); masses must be positive,
    trajectories 1 or 2, the plant one of `PLANTS`.
    """
    from robots.errors import RobotError
    from robots.profiles import profile

    if plant not in PLANTS:
        raise BatchError(f"--plant must be one of {', '.join(PLANTS)}, got {plant!r}")
    for m in masses:
        if not (m > 0 and m < 1e4):
            raise BatchError(f"--masses: each mass must be in (0, 1e4) kg, got {m}")
    for t in trajectories:
        if t not in (1, 2):
            raise BatchError(f"--trajectories: 1 or 2, got {t}")
    for r in robots:
        try:
            prof = profile(r)
        except RobotError as err:
            raise BatchError(f"--robots: {err}") from None
        if not prof.is_mobile_manipulator:
            raise BatchError(f"--robots: {r!r} has no arm on a wheeled base; it cannot push the cart")
    return [
        PushRun(_robot_ref(r), float(m), int(t), arms, cast("PlantName", plant), duration, seed)  # checked above
        for r in robots
        for m in masses
        for t in trajectories
    ]


@dataclass(frozen=True)
class PushJob:
    """The batch job of one push run: takes a run's key, returns its metrics (`PushMetrics.as_dict`)."""

    def __call__(self, key: str) -> dict[str, Any]:
        import robots
        from wholebody.push import TRUE_CART, PushConfig, run_push

        run = PushRun(**json.loads(key))
        robots.load(run.robot)  # a profile its URDF contradicts: one line naming the key
        truth = replace(TRUE_CART, m=run.mass, I=TRUE_CART.I * run.mass / TRUE_CART.m)
        config = PushConfig(
            robot=run.robot,
            trajectory=run.trajectory,
            n_arms=run.arms,
            duration=run.duration,
            seed=run.seed,
            true_params=truth,
            plant=run.plant,
            contact="fixed" if run.plant == "mujoco" else "optimal",  # the MuJoCo grips are welds: no sliding
        )
        return run_push(config).metrics.as_dict()


def done_runs(out: str | os.PathLike) -> set[str]:
    """Return the keys of the runs with an ``ok: true`` line in ``out`` (cut or foreign lines ignored)."""
    done: set[str] = set()
    for rec in ok_records(out):
        try:
            done.add(PushRun(**rec["run"]).key())
        except (KeyError, TypeError, ValueError):  # not a run line, or one of another campaign's format
            continue
    return done


def _as_run_lines(results: Iterable[dict[str, Any]]) -> Iterator[dict[str, Any]]:
    """Turn the engine's lines (keyed by ``path``) into campaign lines (keyed by ``run``)."""
    for rec in results:
        rec = dict(rec)
        run = json.loads(rec.pop("path"))
        yield {"run": run, **rec}


def run_campaign(
    runs: Sequence[PushRun],
    out: str | os.PathLike,
    workers: int | None = 1,
    ray_address: str | None = None,
    progress: bool | None = None,
) -> dict[str, Any]:
    """Run every run not yet done in ``out``; append one JSON line per run as it finishes; return the summary."""
    if os.path.isdir(out):
        raise BatchError(f"--out {out}: is a directory, give a .jsonl file")
    workers = _check_workers(workers, ray_address)
    done = done_runs(out)
    todo = [r.key() for r in runs if r.key() not in done]
    fh = _open_results(out)
    bar = _progress_bar(progress, len(todo))
    t0 = time.perf_counter()
    try:
        tally = _write_results(_as_run_lines(_results(PushJob(), todo, workers, ray_address)), fh, bar, None)
    finally:
        fh.close()
        if bar is not None:
            bar.close()
    wall = time.perf_counter() - t0
    return {
        "backend": "ray" if ray_address is not None else "joblib",
        "workers": workers,
        "runs": len(runs),
        "skipped": len(runs) - len(todo),
        "ran": tally.ok + tally.failed,
        "ok": tally.ok,
        "failed": tally.failed,
        "seconds": round(wall, 3),
        "out": os.path.abspath(os.fspath(out)),
        "table": summary_rows(runs, out),
    }


def summary_rows(runs: Sequence[PushRun], out: str | os.PathLike) -> list[dict[str, Any]]:
    """Return one row per run of ``runs`` from the last line of each in ``out``: its key fields and main metrics."""
    last: dict[str, dict[str, Any]] = {}
    with open(out, encoding="utf-8", errors="replace") as fh:
        for line in fh:
            try:
                rec = json.loads(line)
                last[PushRun(**rec["run"]).key()] = rec
            except (ValueError, TypeError, KeyError):
                continue
    rows = []
    for r in runs:
        rec = last.get(r.key(), {})
        res = rec.get("result") or {}
        sat = res.get("saturation") or {}
        rows.append(
            {
                "robot": os.path.basename(r.robot),
                "mass_kg": r.mass,
                "trajectory": r.trajectory,
                "arms": r.arms,
                "ok": bool(rec.get("ok")),
                "tracking_rms_mm": res.get("tracking_rms_mm"),
                "arm_torque_limit_ratio": res.get("arm_torque_limit_ratio"),
                "saturated_s": round(0.01 * res["saturated_steps"], 2) if "saturated_steps" in res else None,
                "binding": max(sat, key=lambda k: sat[k]["total_s"]) if sat else "",
                "error": rec.get("error", ""),
            }
        )
    return rows


def format_table(rows: Sequence[dict[str, Any]]) -> str:
    """Return the campaign's summary table (one line per run)."""

    def num(v: Any, fmt: str) -> str:
        return "-" if v is None else format(v, fmt)

    head = f"{'robot':<22} {'kg':>6} {'traj':>4} {'arms':>4} {'RMS mm':>8} {'tau/max':>7} {'sat s':>6}  binding / error"
    lines = [head]
    for r in rows:
        tail = r["binding"] if r["ok"] else f"error: {r['error']}"
        lines.append(
            f"{r['robot'][:22]:<22} {r['mass_kg']:>6g} {r['trajectory']:>4} {r['arms']:>4} "
            f"{num(r['tracking_rms_mm'], '.2f'):>8} {num(r['arm_torque_limit_ratio'], '.2f'):>7} "
            f"{num(r['saturated_s'], '.2f'):>6}  {tail}"
        )
    return "\n".join(lines)
