"""A cart file's masses and inertias are checked before anything simulates it, by `push` and `view` alike.

MuJoCo drops a negative ``<inertial mass>`` silently and reads NaN or inf as numbers; a 100 t occupant sinks the
cart into its soft contacts ("does not stand on the floor"). `cart_file.load_cart_file` refuses each in one line
naming the body, and `cartpush view --cart-model` runs the same checks as `cartpush push --cart-model`.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from cartpush.cli import main
from wholebody.push.cart_file import CartFileError, load_cart_file

ROOT = Path(__file__).resolve().parents[2]
WHEELCHAIR = ROOT / "examples/carts/wheelchair.xml"
OCCUPANT = 'mass="70" diaginertia="4.2 4.0 2.2"'


def _variant(tmp_path: Path, old: str, new: str, name: str = "chair.xml") -> Path:
    """Write the wheelchair with `old` replaced by `new` (which must be in the file once)."""
    text = WHEELCHAIR.read_text()
    assert text.count(old) == 1, old
    path = tmp_path / name
    path.write_text(text.replace(old, new))
    return path


@pytest.mark.parametrize(
    "new",
    [
        'mass="-70" diaginertia="4.2 4.0 2.2"',
        'mass="nan" diaginertia="4.2 4.0 2.2"',
        'mass="inf" diaginertia="4.2 4.0 2.2"',
        'mass="70" diaginertia="nan 4.0 2.2"',
    ],
    ids=["negative", "nan", "inf", "nan-inertia"],
)
def test_a_bad_mass_or_inertia_is_refused_naming_the_body(tmp_path, new):
    path = _variant(tmp_path, OCCUPANT, new)
    with pytest.raises(CartFileError, match=r"body 'occupant'.*finite numbers >= 0|body 'occupant'.*not a finite"):
        load_cart_file(path)


def test_a_negative_density_is_refused_naming_the_body(tmp_path):
    path = _variant(tmp_path, '<geom name="seat" type="box"', '<geom name="seat" type="box" density="-1000"')
    with pytest.raises(CartFileError, match=r"geom of body 'cart' has density -1000"):
        load_cart_file(path)


def test_a_cart_heavier_than_a_push_handles_is_refused_naming_the_heaviest_body(tmp_path):
    path = _variant(tmp_path, OCCUPANT, 'mass="100000" diaginertia="4.2 4.0 2.2"')
    with pytest.raises(CartFileError, match=r"weighs 100\d+ kg \(its heaviest body 'occupant': 100000 kg\).*10000 kg"):
        load_cart_file(path)


def test_a_cart_of_a_few_grams_is_refused(tmp_path):
    text = WHEELCHAIR.read_text()
    path = tmp_path / "feather.xml"
    import re

    path.write_text(re.sub(r'mass="[0-9.]+"', 'mass="0.001"', text))
    with pytest.raises(CartFileError, match=r"the cart weighs 0\.\d+ kg.*0\.1 to 10000 kg"):
        load_cart_file(path)


def test_the_example_wheelchair_passes_with_its_mass_and_extent():
    source = load_cart_file(WHEELCHAIR)
    assert source.mass == pytest.approx(87.8, abs=0.05)
    x0, x1, y0, y1 = source.extent
    assert x0 < -0.12 < 0.0 < 0.5 < x1 and y0 < -0.3 and y1 > 0.3  # the handles behind, the footrest ahead


@pytest.mark.parametrize("command", ["push", "view"])
def test_push_and_view_refuse_a_nan_mass_in_one_line_without_a_mujoco_log(tmp_path, monkeypatch, capfd, command):
    path = _variant(tmp_path, OCCUPANT, 'mass="nan" diaginertia="4.2 4.0 2.2"')
    monkeypatch.chdir(tmp_path)
    args = ["push", "--duration", "8", "--json"] if command == "push" else ["view", "--html", "out.html"]
    code = main([*args, "--cart-model", str(path)])
    err = capfd.readouterr().err.strip().splitlines()
    assert code == 2
    assert len(err) == 1 and err[0].startswith(f"cartpush {command}: error: cart file") and "'occupant'" in err[0]
    assert not (tmp_path / "MUJOCO_LOG.TXT").exists()
    assert not (tmp_path / "out.html").exists()


def test_push_refuses_a_negative_mass_instead_of_dropping_it(tmp_path, capfd):
    path = _variant(tmp_path, OCCUPANT, 'mass="-13" diaginertia="4.2 4.0 2.2"')
    code = main(["push", "--duration", "8", "--json", "--cart-model", str(path)])
    err = capfd.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1 and "body 'occupant'" in err[0] and "mass -13 kg" in err[0]


def test_a_heavy_cart_that_does_not_stand_is_said_to_sink_or_tip_not_to_miss_the_floor(tmp_path, capfd):
    """5 t in the wheelchair (within the push's bound): the settle check named the floor's collision flags."""
    path = _variant(tmp_path, OCCUPANT, 'mass="5000" diaginertia="4.2 4.0 2.2"')
    code = main(["push", "--duration", "8", "--json", "--cart-model", str(path)])
    err = capfd.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1, err
    assert "does not stand on the floor" in err[0] and "kg it sinks or tips on its wheels' soft contacts" in err[0]
    assert "contype" not in err[0]
