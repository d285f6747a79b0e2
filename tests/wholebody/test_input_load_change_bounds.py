"""A load change is put in or taken out on the cart (within its plan extent) and leaves a cart a push handles.

``--load-change 4:+5@100,100`` once ran to a true CoM 20 m off the cart and ``4:+1e9`` to a 1e9 kg cart; both
are refused in one line (`wholebody.push.config.check_load_changes`), for the shopping cart and a cart file.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import pytest

from cartpush.cli import main
from wholebody.errors import WholeBodyError
from wholebody.push import PushConfig
from wholebody.push.config import CART_MASS_RANGE_KG, check_load_changes
from wholebody.push.load_change import LoadChange

ROOT = Path(__file__).resolve().parents[2]
WHEELCHAIR = str(ROOT / "examples/carts/wheelchair.xml")


@pytest.mark.parametrize("xy", [(100.0, 100.0), (5.0, 0.0), (0.3, 1.0), (-1.0, 0.0)])
@pytest.mark.parametrize("mass", [5.0, -5.0], ids=["in", "out"])
def test_a_load_off_the_shopping_cart_is_refused_naming_its_extent(xy, mass):
    with pytest.raises(WholeBodyError, match=r"off the cart: the shopping cart spans x in \[-0\.\d+, 0\.\d+\] m"):
        PushConfig(duration=8.0, load_changes=(LoadChange(4.0, mass, xy),))


def test_a_load_on_the_shopping_cart_or_at_its_com_is_accepted():
    PushConfig(duration=8.0, load_changes=(LoadChange(4.0, 5.0, (0.5, 0.1)), LoadChange(5.0, 5.0)))


def test_a_load_off_a_cart_file_is_refused_with_that_carts_extent():
    with pytest.raises(WholeBodyError, match=r"off the cart: cart .*wheelchair\.xml spans x in \[-0\.305, 0\.580\]"):
        PushConfig(
            duration=8.0,
            plant="mujoco",
            contact="fixed",
            cart_model=WHEELCHAIR,
            load_changes=(LoadChange(4.0, 5.0, (1.0, 0.0)),),
        )
    check_load_changes((LoadChange(4.0, 5.0, (0.3, 0.0)),), 8.0, cart_model=WHEELCHAIR)  # on its seat


def test_a_load_making_the_cart_heavier_than_a_push_handles_is_refused():
    hi = CART_MASS_RANGE_KG[1]
    with pytest.raises(WholeBodyError, match=r"puts 1e\+09 kg in.*at most 10000 kg"):
        PushConfig(duration=8.0, load_changes=(LoadChange(4.0, 1e9),))
    with pytest.raises(WholeBodyError, match=r"at t = 5 s puts 6000 kg in.*12020 kg"):  # the two together
        check_load_changes((LoadChange(4.0, 6000.0), LoadChange(5.0, 6000.0)), 8.0)
    with pytest.raises(WholeBodyError, match=r"at most 10000 kg"):  # the wheelchair's 87.8 kg and the load
        check_load_changes((LoadChange(4.0, hi - 50.0),), 8.0, cart_model=WHEELCHAIR)
    check_load_changes((LoadChange(4.0, 6000.0), LoadChange(5.0, -6000.0), LoadChange(6.0, 3000.0)), 8.0)


@pytest.mark.parametrize(
    ("change", "match"),
    [("4:+5@100,100", "off the cart"), ("4:+5@5,0", "off the cart"), ("4:+1e9", "at most 10000 kg")],
)
def test_push_refuses_in_one_line(capsys, change, match):
    code = main(["push", "--duration", "8", "--json", "--load-change", change])
    out = capsys.readouterr()
    lines = out.err.strip().splitlines()
    assert code == 2 and out.out == ""
    assert len(lines) == 1 and lines[0].startswith("cartpush push: error:") and match in lines[0]


def test_demo_refuses_a_load_off_the_cart_before_any_run(monkeypatch, capsys):
    import cartpush.cli.demo as demo
    import wholebody.push.report as report

    def ran(*args, **kwargs):
        raise AssertionError("the demo ran before refusing the load change")

    monkeypatch.setattr(report, "run_demo", ran)
    monkeypatch.setattr(demo, "robot_summary", ran)
    args = argparse.Namespace(duration=8.0, load_change=["4:+5@3,0"], robots_only=False, json=True, out=Path("x"))
    with pytest.raises(WholeBodyError, match="off the cart"):
        demo.run(args)
