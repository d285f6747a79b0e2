"""Issue 14, classes 4 and 8: the log reader — BOM, lone contact column, absurd values, unit plausibility."""

from __future__ import annotations

import numpy as np
import pytest

from cart.errors import LogFormatError
from cart.logs import CartLog, plausibility_warnings, read_log, write_log


def _push(duration=10.0, dt=0.01, speed=0.5, mass_force=10.0):
    t = np.arange(0.0, duration, dt)
    q = np.column_stack([speed * t, 0.1 * np.sin(0.3 * t), 0.2 * np.sin(0.5 * t)])
    g = np.column_stack([mass_force + 2 * np.sin(t), 0 * t, 0.5 * np.sin(2 * t)])
    return CartLog(t=t, q=q, gamma=g)


def test_utf8_bom_is_accepted(tmp_path):
    path = tmp_path / "bom.csv"
    write_log(path, _push())
    text = path.read_text(encoding="utf-8")
    path.write_bytes(b"\xef\xbb\xbf" + text.encode("utf-8"))
    log = read_log(path)
    assert len(log) == 1000 and log.warnings == ()
    gz = tmp_path / "bom.csv.gz"
    import gzip

    gz.write_bytes(gzip.compress(b"\xef\xbb\xbf" + text.encode("utf-8")))
    assert len(read_log(gz)) == 1000


@pytest.mark.parametrize("present, absent", [("contact_x", "contact_y"), ("contact_y", "contact_x")])
def test_lone_contact_column_is_named(tmp_path, present, absent):
    lines = ["t,x,y,theta,fx,fy,tau," + present] + [f"{0.1 * k},{0.01 * k},0,0,1,0,0,0.2" for k in range(5)]
    path = tmp_path / "lone.csv"
    path.write_text("\n".join(lines) + "\n")
    with pytest.raises(LogFormatError, match=f"line 1: column {present} without {absent}"):
        read_log(path)


@pytest.mark.parametrize("value", ["1e300", "-1e300", "1e13"])
def test_absurd_magnitude_is_rejected_with_line_and_column(tmp_path, value):
    lines = ["# note: x", "t,x,y,theta,fx,fy,tau"] + [f"{0.1 * k},{0.01 * k},0,0,1,0,0" for k in range(5)]
    lines[4] = lines[4].replace(",1,0,0", f",{value},0,0")
    path = tmp_path / "big.csv"
    path.write_text("\n".join(lines) + "\n")
    with pytest.raises(LogFormatError, match=r"big\.csv: line 5: column fx: value .* out of range"):
        read_log(path)


def test_existing_structural_checks_still_hold(tmp_path):
    for body, fragment in [
        ("", "empty"),
        ("t,x,y\n1,2,3\n", "missing required column"),
        ("t,x,y,theta,fx,fy,tau\n0,0,0,0,0,0,nan\n", "non-finite"),
        ("t,x,y,theta,fx,fy,tau\n0,0,0,0,0,0,0\n0,0,0,0,0,0,0\n0,0,0,0,0,0,0\n", "strictly"),
    ]:
        path = tmp_path / "bad.csv"
        path.write_text(body)
        with pytest.raises(LogFormatError, match=fragment):
            read_log(path)


@pytest.mark.parametrize(
    "kind, fragment",
    [
        ("degrees", "degrees"),
        ("millimetres", "millimetres"),
        ("milliseconds", "milliseconds"),
        ("glitch", "glitch"),
        ("zero_wrench", "zero throughout"),
    ],
)
def test_unit_mistakes_and_glitches_warn(tmp_path, kind, fragment):
    log = _push()
    t, q, g = log.t.copy(), log.q.copy(), log.gamma.copy()
    if kind == "degrees":
        q[:, 2] = np.degrees(np.unwrap(0.4 * t))
    elif kind == "millimetres":
        q[:, :2] *= 1000.0
    elif kind == "milliseconds":
        t = t * 1000.0
    elif kind == "glitch":
        q[400, 0] += 5.0  # a single 5 m motion-capture glitch
    elif kind == "zero_wrench":
        g[:] = 0.0
    path = tmp_path / f"{kind}.csv"
    write_log(path, CartLog(t=t, q=q, gamma=g), wrap_theta=False)
    log2 = read_log(path)
    assert any(fragment in w for w in log2.warnings), log2.warnings
    if kind == "glitch":
        assert any("line 4" in w for w in log2.warnings)  # names where (line of sample ~400)


def test_wrapped_heading_in_degrees_steps_are_flagged():
    t = np.arange(0.0, 10.0, 0.01)
    theta_deg = (np.degrees(0.8 * t) + 180.0) % 360.0 - 180.0  # wrapped to (-180, 180]
    log = CartLog(
        t=t,
        q=np.column_stack([0.3 * t, 0 * t, np.unwrap(theta_deg)]),
        gamma=np.column_stack([10 + 0 * t, 0 * t, 0 * t]),
    )
    notes = plausibility_warnings(log, raw_theta=theta_deg)
    assert any("degrees" in n for n in notes), notes


@pytest.mark.parametrize(
    "speed, force, dt",
    [
        (0.01, 0.02, 0.01),  # a 1 kg block at 1 cm/s
        (0.8, 120.0, 0.005),  # a 150 kg hospital bed
        (1.5, 30.0, 0.1),  # 10 Hz logging
        (0.2, 5.0, 0.001),
    ],
)  # 1 kHz logging
def test_plausible_but_unusual_data_reads_without_warnings(tmp_path, speed, force, dt):
    path = tmp_path / "odd.csv"
    log = _push(duration=20.0, dt=dt, speed=speed, mass_force=force)
    rng = np.random.default_rng(0)
    noisy = CartLog(t=log.t, q=log.q + rng.normal(size=log.q.shape) * 0.002, gamma=log.gamma)
    write_log(path, noisy)
    assert read_log(path).warnings == ()


def test_corrupt_gzip_stream_is_a_log_format_error(tmp_path):
    import gzip

    good = gzip.compress(("t,x,y,theta,fx,fy,tau\n" + "".join(f"{k},0,0,0,1,0,0\n" for k in range(50))).encode())
    for name, data in (("truncated", good[:-12]), ("bad_deflate", good[:12] + b"\xff" * 40 + good[52:])):
        path = tmp_path / f"{name}.csv.gz"
        path.write_bytes(data)
        with pytest.raises(LogFormatError, match="cannot read the file"):
            read_log(path)
