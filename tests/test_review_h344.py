"""Review of 9a0a99a, f9bc943 and 7113fe8 (h344)."""

from __future__ import annotations

import os

from tlm import storage


def test_a_replaced_host_of_storage_is_what_its_cleaning_asks(tmp_path, monkeypatch):
    """storage._host, replaced (a sweep of another machine sharing the folder, tests/test_sweep_reference_h190.py),
    is the host clean_stale takes for its own, as before the cleaning moved to tlm.storage_live: this machine's
    name on a folder of this process that no writer holds then names another machine's process, left alone."""
    ours = tmp_path / f".out.tmp-{storage.process_tag()}-987654"  # (this process's, no writer of it holds it)
    ours.mkdir()
    monkeypatch.setattr(storage, "_host", lambda: "hElsewhereBox")
    monkeypatch.setattr(storage, "pid_alive", lambda pid: False)
    storage.clean_stale(tmp_path)
    assert ours.is_dir()  # (was: removed, the real host asked)
    monkeypatch.undo()
    storage.clean_stale(tmp_path)
    assert not ours.exists()


def test_a_line_said_straight_to_stderrs_descriptor_escapes_a_surrogate(monkeypatch, capfd):
    """cli_signals._say's fallback (a write to sys.stderr under way where a signal landed: the line goes to file
    descriptor 2 itself) writes a path of bytes not UTF-8 (a surrogate) escaped, as sys.stderr does: it raised
    UnicodeEncodeError, and the line was lost. The byte is ``\\xe8``, as stdout shows it (h352: Python's
    ``\\udce8``)."""
    from tlm import cli_signals

    def reentrant(text: str) -> None:
        raise RuntimeError("reentrant call inside <_io.BufferedWriter name='<stderr>'>")

    monkeypatch.setattr(cli_signals, "_line", reentrant)
    name = os.fsdecode(b"/data/sc\xe8ne.obj")  # (a lone surrogate, \udce8)
    cli_signals._say(f"tlm: error: the output could not be written: {name}")
    assert capfd.readouterr().err == "tlm: error: the output could not be written: /data/sc\\xe8ne.obj\n"
