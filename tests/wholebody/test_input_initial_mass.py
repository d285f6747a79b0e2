"""``--initial-mass`` takes a mass within the carts a push handles: 1e-9 kg once failed as "cart mass must be
positive" and 0.001 kg as "the whole-body velocity QP has no solution", neither naming the option."""

from __future__ import annotations

import pytest

from cartpush.cli import main


@pytest.mark.parametrize("mass", ["1e-9", "0.001", "0.05", "0", "-3", "2e4", "nan", "inf"])
def test_an_initial_mass_out_of_range_is_refused_naming_the_option_and_range(capsys, mass):
    code = main(["push", "--duration", "8", "--json", "--initial-mass", mass])
    out = capsys.readouterr()
    lines = out.err.strip().splitlines()
    assert code == 2 and out.out == ""
    assert len(lines) == 1
    assert lines[0].startswith("cartpush push: error: --initial-mass") and "[0.1, 10000]" in lines[0]


def test_the_bounds_themselves_are_accepted():
    import argparse

    from cartpush.cli import push

    parser = argparse.ArgumentParser()
    push.register(parser.add_subparsers())
    for mass in ("0.1", "10000"):
        args = parser.parse_args(["push", "--duration", "8", "--initial-mass", mass])
        assert push.config_from_args(args).initial_mass == float(mass)
