"""Issue 14, class 8: a broken URDF is the project's RobotError with the parser's message, and leaves no files."""

from __future__ import annotations

import os
import tempfile
from pathlib import Path

import pytest

import robots
from cart.errors import CartpushError
from robots.errors import RobotError

CACHE = Path(tempfile.gettempdir()) / "cartpush_urdf"


def _listing():
    return set(os.listdir(CACHE)) if CACHE.is_dir() else set()


@pytest.mark.parametrize(
    "text, fragment",
    [
        ("<robot", "not well-formed XML"),
        ("", "empty"),
        ("<foo/>", "<robot> root"),
        (
            '<robot name="x"><link name="a"/><joint name="j" type="revolute"><parent link="a"/><child link="b"/>'
            "</joint></robot>",
            "does not specify limits",
        ),
    ],
)
def test_broken_urdf_text_is_a_robot_error_and_leaves_no_cache_file(text, fragment):
    before = _listing()
    with pytest.raises(RobotError, match=fragment) as err:
        robots.load("wmra", urdf_text=text)
    assert isinstance(err.value, CartpushError)
    assert _listing() == before


def test_valid_urdf_text_still_loads_and_keeps_its_file():
    r = robots.load("wmra", urdf_text=robots.wmra_urdf())
    assert r.urdf.is_file() and r.model.nv > 3
