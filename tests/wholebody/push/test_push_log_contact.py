"""`push_log`'s contact columns are the handle point the hand held, in {b}: a cart file's own handle, not the
shopping cart's x = -0.15 m (a log replayed with `cartpush view` drew the force at the wrong place)."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from wholebody.push import PushConfig
from wholebody.contacts.handle import HandleSegment
from wholebody.push.geometry import CartGeometry
from wholebody.push.report import push_log


def _result(config: PushConfig, ys: np.ndarray) -> SimpleNamespace:
    n = ys.size
    return SimpleNamespace(
        config=config,
        t=0.01 * np.arange(n),
        z_meas=np.zeros((n, 6)),
        gamma_measured=np.zeros((n, 3)),
        contact_y=ys[:, None],
        load_changes_true=(),
    )


@pytest.mark.parametrize("x", [-0.15, -2.10])
def test_the_contact_columns_are_the_handle_point_held(x):
    bar = HandleSegment(start_b=(x, -0.3, 0.9), end_b=(x, 0.3, 0.9))
    config = PushConfig(geometry=CartGeometry(handle=bar))
    ys = np.linspace(-0.2, 0.2, 5)
    log = push_log(_result(config, ys))
    np.testing.assert_allclose(log.contact_b, np.column_stack([np.full(5, x), ys]))
