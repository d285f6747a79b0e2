"""A reader that closes the pipe early (``cartpush estimate LOG | head -5``) ends the CLI quietly with 141
(128 + SIGPIPE, as a shell reports it), not "internal error (bug): BrokenPipeError"."""

from __future__ import annotations

import math
import subprocess
import sys

import numpy as np

from cart.logs import CartLog, write_log


def test_a_closed_stdout_ends_quietly_with_141(tmp_path):
    from cart import table1
    from cart.simulate import simulate

    def ctrl(t, q, qd):
        f = 15.0 + 10.0 * math.sin(2.1 * t)
        return np.array([f * math.cos(q[2]), f * math.sin(q[2]), 3.0 * math.sin(1.7 * t)])

    m = simulate(table1.true_params(table1.TESTS[4]), ctrl, 20.0, 0.01).measured
    path = tmp_path / "push.csv"
    write_log(path, CartLog(t=m.t, q=m.q, gamma=m.gamma))
    code = "import sys; from cartpush.cli import main; sys.argv[0] = 'cartpush'; sys.exit(main())"
    proc = subprocess.Popen(
        [sys.executable, "-c", code, "estimate", str(path)], stdout=subprocess.PIPE, stderr=subprocess.PIPE
    )
    assert proc.stdout is not None and proc.stderr is not None
    proc.stdout.close()  # the reader is gone before the first line is written
    err = proc.stderr.read().decode()
    assert proc.wait(timeout=120) == 141
    assert "BrokenPipe" not in err and "internal error" not in err, err
