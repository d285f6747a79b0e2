"""MuJoCo's warnings never flood stderr during a push, nor leave a MUJOCO_LOG.TXT in the working directory: they are
collected (`cart_file.mujoco_warnings`) and said once, on stderr and in the run's JSON."""

from __future__ import annotations

import json

import mujoco
import numpy as np

from cartpush.cli import main
from wholebody.push.cart_file import mujoco_warnings, warnings_summary

UNSTABLE = """<mujoco><worldbody><body><freejoint/><geom size="0.1" mass="1"/></body></worldbody></mujoco>"""


def _blow_up(steps: int = 20) -> None:
    """Step a model whose velocity is NaN `steps` times, resetting it after each: MuJoCo warns at each (once per
    reset: its data counts a warning's repeats)."""
    model = mujoco.MjModel.from_xml_string(UNSTABLE)
    data = mujoco.MjData(model)
    for _ in range(steps):
        mujoco.mj_resetData(model, data)
        data.qvel[:] = np.nan
        mujoco.mj_step(model, data)


def test_the_warnings_are_collected_not_printed_nor_logged(tmp_path, monkeypatch, capfd):
    monkeypatch.chdir(tmp_path)
    before = mujoco.get_mju_user_warning()
    with mujoco_warnings() as warned:
        _blow_up()
    assert len(warned) >= 20 and all("Nan, Inf or huge value" in w for w in warned)
    assert capfd.readouterr().err == ""
    assert not (tmp_path / "MUJOCO_LOG.TXT").exists()
    assert mujoco.get_mju_user_warning() is before
    summary = warnings_summary(warned)
    assert (
        summary.startswith(f"MuJoCo warned {len(warned)} time(s): Nan, Inf or huge value") and "Time =" not in summary
    )


def test_an_enclosing_collector_gets_the_inner_blocks_warnings():
    with mujoco_warnings() as outer:
        with mujoco_warnings() as inner:
            _blow_up(3)
    assert len(inner) == 3 and outer == inner


def test_push_says_mujocos_warnings_once(tmp_path, monkeypatch, capfd):
    import wholebody.push as push_pkg

    real = push_pkg.run_push

    def warning_run(config, progress=None):
        _blow_up(50)  # as an unstable MuJoCo step during the run would
        return real(config, progress=progress)

    monkeypatch.setattr(push_pkg, "run_push", warning_run)
    monkeypatch.chdir(tmp_path)
    code = main(["push", "--trajectory", "1", "--duration", "8", "--no-estimation", "--json"])
    out = capfd.readouterr()
    assert code == 0
    lines = out.err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("cartpush push: warning: MuJoCo warned 50 time(s)"), out.err
    assert json.loads(out.out)["mujoco_warnings"]["count"] == 50
    assert not (tmp_path / "MUJOCO_LOG.TXT").exists()
