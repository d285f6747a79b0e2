"""The sample bag shipped in cartpush/ros/data/ (the README's first ten minutes): `cartpush import` reads it.

The bag is written by cartpush/ros/data/make_sample_bag.py from a simulated push; here the same push is
recomputed and the imported log must equal its measured log (pose and wrench through the static TF link
from the sensor on the handle), so a stale or broken bag fails.
"""

from __future__ import annotations

import importlib.util
import json
from pathlib import Path

import numpy as np
import pytest

from cart.logs import read_log
from cartpush.cli import main

DATA = Path(__file__).resolve().parents[2] / "cartpush" / "ros" / "data"
BAG = DATA / "sample_push.bag"


def _generator():
    spec = importlib.util.spec_from_file_location("make_sample_bag", DATA / "make_sample_bag.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_sample_bag_is_small_and_lists_its_topics(capsys):
    assert BAG.is_file() and 100e3 < BAG.stat().st_size < 1e6
    assert main(["import", str(BAG), "--list", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    uses = {t["name"]: t["use"] for t in out["topics"]}
    assert uses["/mocap/cart"] == "pose" and uses["/ft_sensor/wrench"] == "wrench"


def test_import_of_the_sample_bag_gives_the_simulated_push(tmp_path):
    out = tmp_path / "run.csv"
    args = ["import", str(BAG), "-o", str(out), "--pose-topic", "/mocap/cart", "--wrench-topic", "/ft_sensor/wrench"]
    assert main(args) == 0
    got, want = read_log(out), _generator().sample_log()
    assert len(got.t) == len(want.t) == 1601
    np.testing.assert_allclose(got.t, want.t - want.t[0], atol=1e-6)
    np.testing.assert_allclose(got.q, want.q, atol=1e-6)
    np.testing.assert_allclose(got.gamma, want.gamma, atol=1e-6)
    assert np.ptp(got.q[:, 0]) > 1.0 and np.abs(got.gamma[:, 0]).max() > 5.0  # a real push, not zeros


def test_sample_bag_wrench_is_in_the_sensor_frame():
    """The bag stores the wrench rotated into the handle sensor's frame: the import must undo the static TF."""
    gen = _generator()
    f, m = gen.sensor_wrench(0.3, np.array([10.0, 2.0, 1.5]))
    assert abs(f[0] - 10.0) > 1.0  # not the world force
    R = gen._rz(0.3) @ gen._rz(gen.SENSOR_YAW)
    np.testing.assert_allclose((R @ f)[:2], [10.0, 2.0], atol=1e-12)
    r = gen._rz(0.3) @ gen.SENSOR_B
    assert (R @ m)[2] + np.cross(r, R @ f)[2] == pytest.approx(1.5)


def test_estimate_of_the_sample_bag_finds_the_carts_mass(tmp_path, capsys):
    """The README's first ten minutes: import the sample bag, then `cartpush estimate` gives the 20 kg cart."""
    out = tmp_path / "run.csv"
    topics = ["--pose-topic", "/mocap/cart", "--wrench-topic", "/ft_sensor/wrench"]
    assert main(["import", str(BAG), "-o", str(out), *topics]) == 0
    capsys.readouterr()
    assert main(["estimate", str(out), "--json"]) == 0
    est = json.loads(capsys.readouterr().out)
    truth = _generator().sample_config().true_params
    mass = est["mass"]
    assert abs(mass - truth.m) < 1.5, f"estimated {mass} kg for a {truth.m} kg cart"
