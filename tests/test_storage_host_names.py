"""Two machines sharing a folder (NFS) whose writers have one process id (tlm.storage): the names a
writer makes beside its destination carry the host as well as the pid, so the two never share a
temporary file (``write_atomic``) nor a claim folder (``claim_folder``), as they did when the pid
alone named them. What an older tlm left (``.X.tmp<pid>``) is still recognised as a writer's."""

from __future__ import annotations

import os
import socket
from pathlib import Path

from tlm import storage
from tlm.storage import check_destination, claim_folder, write_atomic


def on_host(monkeypatch, name: str) -> None:
    """From now on this process is on the machine ``name`` (its pid unchanged)."""
    monkeypatch.setattr(socket, "gethostname", lambda: name)


def hidden(folder: Path) -> set[Path]:
    return {p for p in folder.iterdir() if p.name.startswith(".")}


def test_two_hosts_with_one_pid_never_share_a_temporary_file(tmp_path, monkeypatch):
    """alpha is mid-write when beta, the same pid on another machine (a process of its own, so
    none of alpha's temporary files is noted as this one's), writes the same path and finishes:
    alpha's temporary file is untouched (not truncated, not renamed away) and its write, last
    to finish, wins whole."""
    path = tmp_path / "shared" / "k.json"
    path.parent.mkdir()
    on_host(monkeypatch, "alpha")
    with write_atomic(path) as a:
        a.write("from alpha")
        a.flush()
        (alphas,) = hidden(path.parent)
        on_host(monkeypatch, "beta")
        alpha_files = storage._FILES
        storage._FILES = set()  # (another machine's process: its own blocks)
        try:
            with write_atomic(path) as b:
                (betas,) = hidden(path.parent) - {alphas}
                b.write("from beta")
        finally:
            storage._FILES = alpha_files
        assert path.read_text() == "from beta"
        assert alphas.read_text() == "from alpha"
        on_host(monkeypatch, "alpha")
    assert path.read_text() == "from alpha"
    assert hidden(path.parent) == set()
    pid = os.getpid()
    assert (alphas.name, betas.name) == (f".k.json.tmphalpha-{pid}", f".k.json.tmphbeta-{pid}")


def test_two_hosts_with_one_pid_claim_a_folder_through_siblings_of_their_own(tmp_path, monkeypatch):
    """claim_folder prepares the folder in a sibling that names the host; a folder holding only a
    marker being written, by this tlm (host and pid) or an older one (pid alone), is still a
    claim in progress, which check_destination accepts."""
    made: list[str] = []
    real = storage.write_file

    def noting(path, data):
        made.append(Path(path).parent.name)
        real(path, data)

    monkeypatch.setattr(storage, "write_file", noting)
    for host in ("alpha", "beta"):
        on_host(monkeypatch, host)
        out = tmp_path / host / "sweep"
        out.parent.mkdir()
        assert claim_folder(out, "sweep.yaml", host)
        assert (out / "sweep.yaml").read_text() == host
    pid = os.getpid()
    assert made == [f".sweep.claimhalpha-{pid}", f".sweep.claimhbeta-{pid}"]

    for older, name in enumerate((f".sweep.yaml.tmp{storage.process_tag()}", ".sweep.yaml.tmp4242")):
        out = tmp_path / f"claimed{older}"
        out.mkdir()
        (out / name).write_text("half")  # (another writer's marker, mid-write)
        assert check_destination(out, "sweep.yaml") == out.resolve()
