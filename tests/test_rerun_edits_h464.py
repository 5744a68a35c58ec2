"""h464: what a rerun keeps of a file tlm wrote that the user edited, and of a folder whose listing is gone.

* A file an output wrote that its user then edited in place (an annotated ``images/pmap.png``, a hand-edited
  results file) was the output's to a rerun: removed unsaid where the new output does not write it, replaced
  unsaid where it does. The listing (``.tlm-written``) now gives each file's size and modification time; a file
  no longer as written is the user's: kept, or named in the warning where the new output writes that path. A
  listing of paths alone (a tlm's before) is read as it was.
* A folder whose listing was deleted had its own folders replaced whole, the user's files in them with them,
  unsaid: what the new output writes there is its own, the rest is kept, and a warning names the folder and it.
* The warning on the user's paths a new output took listed them by hand: :func:`tlm.config_words.listing` now
  ("'a', 'b' and 'c'"; six named whole, never "and 1 more").
"""

from __future__ import annotations

import os
from pathlib import Path

from tlm.cli import main
from tlm.storage_carry import LISTING, lost_line, unlisted_line

from .test_review_h456 import _files
from .test_review_h456 import _output as _output456

CORNELL = str(Path(__file__).resolve().parents[1] / "configs" / "cornell.yaml")
RUN = ["run", CORNELL, "--set", "resolution=[8,8]", "--no-report", "--no-progress"]


def _output(out: Path, files: dict[str, str], owned=("m", "t.json", "images", "aov", "report")) -> None:
    """An output of ``files`` (``m``, the marker, among them) written into ``out`` by :func:`atomic_folder`."""
    _output456(out, files, owned)


def _edit(path: Path, text: str) -> None:
    """``path`` written with ``text``, its modification time a second later than it was (an edit of the same size
    within the file system's clock tick is told by no stamp: the test's edits are not)."""
    was = os.stat(path).st_mtime_ns
    path.write_text(text)
    os.utime(path, ns=(was + 10**9, was + 10**9))


def _warnings(err: str) -> list[str]:
    return [line for line in err.splitlines() if "warning" in line]


def test_a_file_the_output_wrote_that_the_user_edited_is_the_user_s(tmp_path, capsys):
    """Edited and not written again: kept (in a folder, and an owned file at the top); edited and written again:
    replaced and named, a same-size edit too; unedited and not written again: removed, as before."""
    out = tmp_path / "o"
    _output(out, {"m": "1", "t.json": "{}", "images/pmap.png": "1", "images/a.png": "1", "images/old.png": "1",
                  "aov/w.npz": "1"})
    _edit(out / "images" / "pmap.png", "annotated")
    _edit(out / "images" / "a.png", "2")  # (the same size: its time tells it)
    _edit(out / "t.json", '{"note": "mine"}')
    _edit(out / "m", "edited")
    capsys.readouterr()
    _output(out, {"m": "2", "images/a.png": "3"})
    assert _files(out) == {"m": "2", "t.json": '{"note": "mine"}', "images/pmap.png": "annotated",
                           "images/a.png": "3"}
    (line,) = _warnings(capsys.readouterr().err)
    assert (f"{out}: 'images/a.png' and 'm' (yours: not written by the earlier output, or changed since) were "
            "replaced by this output's own of the same path") in line
    # a kept file is the user's from then on, as one the user put there; a rerun as written says nothing
    _output(out, {"m": "3", "images/a.png": "3"})
    assert _files(out) == {"m": "3", "t.json": '{"note": "mine"}', "images/pmap.png": "annotated",
                           "images/a.png": "3"}
    assert not _warnings(capsys.readouterr().err)
    # a listing of paths alone (a tlm's before the stamps) is read as it was: an edited file it names is the
    # output's, and so is an owned file at the top, listed or not
    _output(out, {"m": "4", "images/a.png": "4", "images/b.png": "4"})
    (out / LISTING).write_text("images\nimages/a.png\nimages/b.png\nm\n")
    _edit(out / "images" / "b.png", "edited")
    _output(out, {"m": "5", "images/a.png": "5"})
    assert _files(out) == {"m": "5", "images/pmap.png": "annotated", "images/a.png": "5"}
    assert not _warnings(capsys.readouterr().err)


def test_a_rerun_of_tlm_run_names_the_user_s_edits_it_replaced(tmp_path, cache, capsys):
    """Through ``tlm run``: a rerun as written says nothing (no file of a run changes after its listing); an
    annotated image and a hand-edited results.json the rerun writes again are named."""
    out = tmp_path / "r"
    assert main([*RUN, "--out", str(out)]) == 0
    assert "\t" in (out / LISTING).read_text()
    capsys.readouterr()
    assert main([*RUN, "--out", str(out)]) == 0
    assert "yours" not in capsys.readouterr().err
    with open(out / "images" / "composite.png", "ab") as f:
        f.write(b"annotated")
    _edit(out / "results.json", (out / "results.json").read_text().replace("{", '{"note": "mine", ', 1))
    assert main([*RUN, "--out", str(out)]) == 0
    (line,) = [x for x in capsys.readouterr().err.splitlines() if "yours" in x]
    assert "'images/composite.png' and 'results.json' (yours" in line


def test_a_folder_whose_listing_was_deleted_keeps_what_the_new_output_does_not_write(tmp_path, capsys):
    """What the new output writes is its own (unsaid: nothing tells whose it was); the rest of the output's own
    folders is kept (the user's files among it: they were removed), the warning naming the folder and it; an
    owned file and report/ are the output's, as before."""
    out = tmp_path / "o"
    _output(out, {"m": "1", "t.json": "1", "images/a.png": "1", "images/b.png": "1", "aov/w.npz": "1"})
    for rel in ("images/mine.png", "images/notes/fit.py", "report/index.html", "notes.md"):
        (out / rel).parent.mkdir(parents=True, exist_ok=True)
        (out / rel).write_text("mine")
    _edit(out / "images" / "a.png", "annotated")
    (out / LISTING).unlink()
    capsys.readouterr()
    _output(out, {"m": "2", "images/a.png": "2"})
    assert _files(out) == {"m": "2", "images/a.png": "2", "images/b.png": "1", "images/mine.png": "mine",
                           "images/notes/fit.py": "mine", "aov/w.npz": "1", "notes.md": "mine"}
    (line,) = _warnings(capsys.readouterr().err)
    assert line.endswith(f"{out} has no {LISTING} (deleted, or written by a tlm older than it), which tells tlm's "
                         "files from yours: 'aov', 'images/b.png', 'images/mine.png' and 'images/notes', which this "
                         "output does not write, were kept as yours (remove any an earlier output wrote: it is not "
                         "this output's; a report leaves out what the output's listing does not name)")
    # the new output's listing: what it kept is the user's from then on, as any file the user put there
    _output(out, {"m": "3", "images/a.png": "3"})
    assert _files(out)["aov/w.npz"] == "1" and not _warnings(capsys.readouterr().err)


def test_the_warnings_list_their_paths_the_one_way(tmp_path):
    """:func:`tlm.config_words.listing`: six paths named whole (it said 'and 1 more'), seven as five and 2 more."""
    six = [f"images/p{i}.png" for i in range(6)]
    assert lost_line(tmp_path, six).startswith(f"{tmp_path}: 'images/p0.png', 'images/p1.png', 'images/p2.png', "
                                               "'images/p3.png', 'images/p4.png' and 'images/p5.png' (yours")
    assert "'images/p4.png' and 2 more (yours" in lost_line(tmp_path, [*six, "images/p6.png"])
    assert "'images/p0.png' (yours" in lost_line(tmp_path, six[:1])
    assert "'a', which this output does not write, was kept as yours" in unlisted_line(tmp_path, ["a"])
