"""Issue 14: the CLI's error contract (one line, exit 2 / 1), lazy --help, option validation (class 6)."""

from __future__ import annotations

import json
import subprocess
import sys

import pytest

from cart.errors import CartpushError
from cartpush.cli import main, preprocess_argv
from tests.cartpush.cli_helpers import one_error_line, tiny_log


def _strict(text: str):
    def refuse(name):
        raise ValueError(f"non-strict JSON constant {name}")

    return json.loads(text, parse_constant=refuse)


# -- one root exception ---------------------------------------------------------------------------
def test_every_package_error_derives_from_the_root():
    """Every exception class defined in the installed packages derives from the one root (cart.errors); warnings
    (a `Warning` is an `Exception` too) are not errors and are left out."""
    import importlib
    import inspect
    import pkgutil

    found = []
    for package in ("cart", "robots", "wholebody", "cartpush"):
        pkg = importlib.import_module(package)
        for info in pkgutil.walk_packages(pkg.__path__, prefix=f"{package}."):
            if info.name.endswith("__main__"):
                continue
            module = importlib.import_module(info.name)
            for _, cls in inspect.getmembers(module, inspect.isclass):
                if issubclass(cls, Exception) and not issubclass(cls, Warning) and cls.__module__ == module.__name__:
                    found.append(cls)
    assert len(found) >= 10
    bad = [f"{c.__module__}.{c.__qualname__}" for c in found if not issubclass(c, CartpushError)]
    assert not bad
    assert all(issubclass(c, ValueError) for c in found)


# -- the mapping in main --------------------------------------------------------------------------
def test_internal_error_is_one_line_exit_1_and_debug_reraises(monkeypatch, capsys):
    import cartpush.cli.plan_contacts as mod

    def boom(args):
        raise ZeroDivisionError("division by zero\nsecond line")

    monkeypatch.setattr(mod, "run", boom)
    assert main(["plan-contacts", "--wrench", "1", "0", "0"]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1
    assert err[0].startswith("cartpush plan-contacts: internal error (bug): ZeroDivisionError: division by zero")
    assert "--debug" in err[0]
    with pytest.raises(ZeroDivisionError):
        main(["--debug", "plan-contacts", "--wrench", "1", "0", "0"])
    capsys.readouterr()
    assert main(["--debug", "track", "line", "--rate", "nan"]) == 2  # bad input stays one line with --debug
    one_error_line(capsys, "track")


def test_no_command_is_one_line(capsys):
    assert main([]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err == ["cartpush: error: no command given (see cartpush --help)"]


def test_missing_file_and_directory_are_user_errors(tmp_path, capsys):
    assert main(["estimate", str(tmp_path / "nope.csv")]) == 2
    one_error_line(capsys, "estimate")
    assert main(["diagnose", str(tmp_path)]) == 2
    one_error_line(capsys, "diagnose")


def test_argparse_errors_are_one_line(capsys):
    with pytest.raises(SystemExit) as exc:
        main(["track", "circle"])
    assert exc.value.code == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("cartpush track: error:")


def test_help_imports_no_command_module():
    code = (
        "import sys\nfrom cartpush.cli import main\n"
        "try:\n    main(['--help'])\nexcept SystemExit:\n    pass\n"
        "heavy = [m for m in ('pinocchio', 'meshcat', 'scipy', 'wholebody.viz', 'cart.diagnose', 'placo')"
        " if m in sys.modules]\nprint('HEAVY', heavy)"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert "HEAVY []" in out
    for command in ("diagnose", "track", "view", "push", "demo", "reproduce", "plan-contacts"):
        code2 = code.replace("['--help']", f"['{command}', '--help']")
        out = subprocess.run([sys.executable, "-c", code2], capture_output=True, text=True, check=True).stdout
        assert "HEAVY []" in out, (command, out)


# -- option validation ----------------------------------------------------------------------------
@pytest.mark.parametrize(
    "argv, fragment",
    [
        (["diagnose", "LOG", "--threshold", "nan"], "--threshold"),
        (["diagnose", "LOG", "--threshold", "-5"], "--threshold"),
        (["diagnose", "LOG", "--threshold", "inf"], "--threshold"),
        (["reproduce", "--seed", "-1"], "--seed"),
        (["reproduce", "--duration", "inf"], "--duration"),
        (["reproduce", "--duration", "1e7"], "--duration"),
        (["reproduce", "--duration", "4.9"], "after t = 5 s"),
        (["reproduce", "--duration", "nan"], "--duration"),
        (["push", "--seed", "-1"], "--seed"),
        (["push", "--duration", "1e7"], "--duration"),
        (["push", "--initial-mass", "nan"], "--initial-mass"),
        (["demo", "--duration", "inf"], "--duration"),
        (["track", "line", "--duration", "1e7"], "--duration"),
        (["track", "line", "--rate", "nan"], "--rate"),
        (["track", "line", "--band", "nan"], "--band"),
        (["plan-contacts", "--wrench", "10", "0", "0", "--arms", "2", "--min-spacing", "nan"], "--min-spacing"),
        (["plan-contacts", "--wrench", "10", "0", "0", "--arms", "2", "--min-spacing", "-1"], "--min-spacing"),
        (["plan-contacts", "--wrench", "nan", "0", "0"], "--wrench"),
        (["view", "--scenario", "3", "--duration", "inf", "--html", "OUT/x.html"], "--duration"),
        (["view", "--scenario", "12", "--html", "OUT/x.html"], "--scenario"),
        (
            ["view", "LOG", "--duration", "-1", "--html", "OUT/x.html"],
            "--duration -1: the simulated seconds of --scenario",
        ),
    ],
)
def test_bad_options_exit_2_before_work(argv, fragment, tmp_path, capsys):
    log = tiny_log(tmp_path / "log.csv")
    argv = [a.replace("LOG", log).replace("OUT", str(tmp_path)) for a in argv]
    assert main(argv) == 2
    assert fragment in one_error_line(capsys, argv[0])


def test_negative_wrench_in_e_notation_is_a_value(capsys):
    assert preprocess_argv(["plan-contacts", "--wrench", "-1e3", "0", "-2"])[0][2] == " -1e3"
    assert main(["plan-contacts", "--wrench", "-1e2", "0", "0", "--json"]) == 0
    out = _strict(capsys.readouterr().out)
    assert out["gamma_achieved"][0] == pytest.approx(-100.0, abs=1e-3)


def test_a_negative_load_change_time_is_a_value_refused_by_its_own_check(capsys):
    """``--load-change -1:+5`` read as an option gave argparse's "expected one argument"."""
    assert preprocess_argv(["push", "--load-change", "-1:+5"])[0][2] == " -1:+5"
    assert preprocess_argv(["push", "-h"])[0][1] == "-h"
    assert main(["push", "--duration", "8", "--load-change", "-1:+5"]) == 2
    assert "a load change's time must be t >= 0 s, got -1 s (for +5 kg)" in one_error_line(capsys, "push")


def test_unwritable_out_fails_before_the_computation(tmp_path, capsys):
    blocker = tmp_path / "file"
    blocker.write_text("x")
    log = tiny_log(tmp_path / "log.csv")
    assert main(["diagnose", log, "--out", str(blocker / "plots")]) == 2
    assert "--out" in one_error_line(capsys, "diagnose")
    assert main(["reproduce", "--tests", "1", "--out", str(blocker)]) == 2
    one_error_line(capsys, "reproduce")
    assert main(["track", "line", "--duration", "1", "--out", str(blocker / "a.csv")]) == 2
    one_error_line(capsys, "track")
    assert main(["view", "--robot", "wmra", "--html", str(blocker / "a.html")]) == 2
    one_error_line(capsys, "view")
    # a directory that does not exist yet is created
    assert main(["track", "line", "--duration", "0.5", "--out", str(tmp_path / "new" / "run.csv"), "--json"]) == 0
    assert (tmp_path / "new" / "run.csv").is_file()


def test_track_leaving_the_band_is_said(capsys):
    # 0.1 mm: far too tight for the sine (the base ends ~0.2 m out whatever the rounding; at 1 mm the outcome
    # depends on last-bit rounding in the degenerate band QP, see docs/wholebody.md)
    assert main(["track", "sine", "--band", "0.0001", "--duration", "3", "--json"]) == 0
    cap = capsys.readouterr()
    out = _strict(cap.out)
    assert out["band_respected"] is False and out["warnings"]
    assert "left the safety band" in cap.err
    assert main(["track", "line", "--band", "5", "--duration", "2", "--json"]) == 0
    out = _strict(capsys.readouterr().out)
    assert out["band_respected"] is True and out["warnings"] == []
