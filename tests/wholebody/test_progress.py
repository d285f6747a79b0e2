"""Progress bars (`wholebody.progress`): on a terminal only, never with --json (issue 16 item 7)."""

from __future__ import annotations

import io
import json
import sys

import pytest

from wholebody.progress import progress_bar, show_progress


class FakeTerminal(io.StringIO):
    """A stderr that says it is a terminal and keeps what is written to it."""

    def isatty(self) -> bool:
        return True


def test_show_progress_only_on_a_terminal_without_json(monkeypatch):
    monkeypatch.setattr(sys, "stderr", io.StringIO())  # not a TTY (pytest's capture, a pipe, a file)
    assert not show_progress()
    monkeypatch.setattr(sys, "stderr", FakeTerminal())
    assert show_progress() and not show_progress(json_output=True)


def test_progress_bar_yields_every_item_and_draws_only_when_enabled(monkeypatch):
    term = FakeTerminal()
    monkeypatch.setattr(sys, "stderr", term)
    assert list(progress_bar(range(5), desc="x", enabled=False)) == list(range(5))
    assert term.getvalue() == ""
    assert list(progress_bar(range(5), desc="runs", total=5)) == list(range(5))  # enabled: a terminal
    assert "runs" in term.getvalue() and "/5" in term.getvalue()  # the bar (cleared at the end: leave=False)


@pytest.mark.parametrize("json_flag", [True, False])
def test_push_draws_a_bar_on_a_terminal_but_not_with_json(monkeypatch, capsys, json_flag):
    from cartpush.cli import main

    term = FakeTerminal()
    monkeypatch.setattr(sys, "stderr", term)
    args = ["push", "--trajectory", "1", "--duration", "8", "--contact", "fixed"] + (["--json"] if json_flag else [])
    assert main(args) == 0
    out = capsys.readouterr().out
    if json_flag:
        json.loads(out)  # stdout is pure JSON
        assert term.getvalue() == ""
    else:
        assert "push" in term.getvalue() and "/801" in term.getvalue()
        assert "unobservable" in out
