"""tlm.claims.sharing on a folder that machines share: a holder records its host with its pid,
and a refusal names the holder's machine; another machine's process is never taken for one
of this machine's of the same pid (its processes cannot be checked from here). A record
of an older tlm (its pid alone) is still read."""

from __future__ import annotations

import fcntl
import os
import re
from contextlib import contextmanager

import pytest

from tlm import claims, storage
from tlm.errors import InputError


@contextmanager
def held(path, record: str):
    """``path`` held as another process would hold it: ``record`` in it, a shared flock on an
    open file of its own (flock locks belong to the open file, so this process's own
    sharing() is refused by it)."""
    path.write_text(record)
    fd = os.open(path, os.O_RDWR)
    try:
        fcntl.flock(fd, fcntl.LOCK_SH)
        yield
    finally:
        os.close(fd)


def refusal(out) -> str:
    with pytest.raises(InputError) as e, claims.sharing(out, "mine", "sweep"):
        pytest.fail("a second identity got the folder")
    return str(e.value)


def test_a_holder_records_its_host_and_pid_and_the_refusal_names_this_machine(tmp_path):
    out = tmp_path / "o"
    out.mkdir()
    with claims.sharing(out, "theirs", "sweep"):
        assert (out / ".tlm-running-theirs").read_text().strip() == f"{storage._host()}-{os.getpid()}"
        said = refusal(out)
    assert f"(process {os.getpid()} on this machine, {storage._host()[1:]} (" in said  # (then its command line)
    assert "another machine" not in said


def test_another_machines_holder_is_named_with_its_host_not_taken_for_this_machines_pid(tmp_path):
    out = tmp_path / "o"
    out.mkdir()
    other = "hnodeB" if storage._host() != "hnodeB" else "hnodeC"
    # the other machine's process has this process's pid: alive here, which says nothing of it
    with held(out / ".tlm-running-theirs", f"{other}-{os.getpid():<40}\n"):
        said = refusal(out)
    assert re.search(rf"another sweep of other points is writing into .* \(process {os.getpid()} on host "
                     rf"{other[1:]}, another machine: its processes cannot be checked from this one\): "
                     "wait for it to end, or give another folder", said), said
    assert "this machine" not in said
    assert (out / ".tlm-running-theirs").is_file()  # (held: left as it was)


def test_an_older_tlms_record_is_read_and_a_longer_record_under_a_shorter_one_is_not(tmp_path):
    """An older tlm wrote its pid alone, padded to 12 characters: still read (its host is not
    known). Holders of one identity overwrite each other's record in place: a record of
    another width leaves the tail of the longer one, which is not read as part of it."""
    out = tmp_path / "o"
    out.mkdir()
    with held(out / ".tlm-running-old", f"{4242:<12d}\n"):
        assert "(process 4242): wait for it to end" in refusal(out)
    with held(out / ".tlm-running-old", f"{4242:<12d}\n{storage._host()}-99999 \n"):
        assert "(process 4242): wait for it to end" in refusal(out)
    record = f"{storage._host()}-{os.getpid()}".ljust(63) + "\n"
    with held(out / ".tlm-running-new", f"{4242:<12d}\n" + record[13:]):  # (an old holder wrote last)
        assert "(process 4242): wait for it to end" in refusal(out)
    with held(out / ".tlm-running-new", "garbage\n"):
        assert "(process ?): wait for it to end" in refusal(out)
    (out / ".tlm-running-new").unlink()
    with held(out / ".tlm-running-new", record):
        said = refusal(out)
    assert f"(process {os.getpid()} on this machine, " in said
