"""A fixed contact point off the handle is refused naming where it came from and the handle's span; it failed
as "the arm holds no handle point with margin: beyond an unreachable point"."""

from __future__ import annotations

import pytest

from wholebody.errors import WholeBodyError
from wholebody.push import PushConfig


@pytest.mark.parametrize("ys", [(3.0,), (-0.4,), (0.0, 0.6)])
def test_a_fixed_contact_off_the_handle_names_the_span(ys):
    cfg = PushConfig(contact="fixed", fixed_contact_y=ys, n_arms=len(ys))
    with pytest.raises(
        WholeBodyError, match=r"fixed_contact_y: contact y = .* off the cart's handle, which spans y in \[-0.25, 0.25\]"
    ):
        cfg.contact_y0()


@pytest.mark.parametrize("ys", [(0.25,), (-0.25,), (-0.2, 0.2)])
def test_contacts_on_the_handle_are_kept(ys):
    cfg = PushConfig(contact="fixed", fixed_contact_y=ys, n_arms=len(ys))
    assert list(cfg.contact_y0()) == sorted(ys)
