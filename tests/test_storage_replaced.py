"""A destination another writer replaces while it is checked (tlm.storage.check_destination):
the check is of one folder, never the marker of one and the entries of the next."""

from __future__ import annotations

from pathlib import Path

from tlm import storage


def test_a_folder_replaced_while_it_is_checked_is_an_earlier_output(tmp_path, monkeypatch):
    """Another writer renames the old output aside and its own into place: a writer that looked
    for the marker between the two renames (no folder, so no marker) and listed the folder after
    them (the new output: its marker and its files) goes on, where it refused it as "not an
    earlier tlm output (no m)" (tests/test_storage_threads.py's threads, 1 time in ~300 with 8)."""
    out = tmp_path / "r"
    for folder, who in ((out, "old"), (tmp_path / ".r.tmp-other", "new")):
        folder.mkdir()
        (folder / "m").write_text(who)
        (folder / "also").write_text(who)
    real = Path.is_file

    def swapped_meanwhile(path):  # (the other writer's two renames, the marker looked for between them)
        if path == out.resolve() / "m" and (tmp_path / ".r.tmp-other").exists():
            out.rename(tmp_path / ".r.old-other")
            answer = real(path)
            (tmp_path / ".r.tmp-other").rename(out)
            return answer
        return real(path)

    monkeypatch.setattr(Path, "is_file", swapped_meanwhile)
    assert storage.check_destination(out, "m") == out.resolve()
    assert (out / "m").read_text() == "new"
