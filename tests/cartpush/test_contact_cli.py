"""`cartpush plan-contacts`: JSON fields, consistency with the grasp map, bad input -> exit 2."""

import json

import numpy as np

from cartpush.cli import main
from wholebody.contacts.handle import cart_wrench


def test_plan_contacts_json(capsys):
    assert main(["plan-contacts", "--wrench", "40", "0", "-2", "--arms", "2", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert set(out) >= {"contacts", "residual", "effort"}
    pts = [c["point_b"] for c in out["contacts"]]
    W = np.array([c["wrench_ee"] for c in out["contacts"]])
    assert [c["arm"] for c in out["contacts"]] == [0, 1]
    assert abs(pts[1][1] - pts[0][1]) >= 0.2 - 1e-6
    assert np.allclose(cart_wrench(pts, W), [40.0, 0.0, -2.0], atol=1e-4)  # JSON rounds to 1e-6
    assert out["residual"] < 1e-8
    assert out["effort"] == np.sum(W**2) or abs(out["effort"] - np.sum(W**2)) < 1e-3


def test_plan_contacts_infeasible_and_bad_input(capsys):
    assert main(["plan-contacts", "--wrench", "-400", "0", "0"]) == 2
    err = capsys.readouterr().err
    assert "grip pull limit" in err and "closest achievable" in err and len(err.strip().splitlines()) == 1
    assert main(["plan-contacts", "--wrench", "4", "0", "0", "--handle-width", "-1"]) == 2
    assert main(["plan-contacts", "--wrench", "4", "0", "0", "--arms", "3", "--handle-width", "0.3"]) == 2
