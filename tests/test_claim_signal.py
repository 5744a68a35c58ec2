"""A signal as a run's destination is claimed (tlm.claims.claimed): the claim file is made, then
held; a signal between the two left the file behind (``.r.tlm-running``, beside the folder)."""

from __future__ import annotations

import os
import signal

import pytest

from tlm import claims, cli_signals


@pytest.mark.skipif(not hasattr(signal, "SIGHUP"), reason="no SIGHUP here")
def test_a_signal_as_the_claim_is_taken_leaves_no_claim_file(tmp_path, monkeypatch):
    """SIGHUP just after the claim file was made and locked, before the claim was held (the
    moment tests/test_faults_h121.py's run is signalled, as it sees the file appear): the command
    stops as before, and the file is removed with the claim (it was left, 1 run in ~3,900 tests)."""
    real = claims._take_claim

    def signalled(*a, **k):
        taken = real(*a, **k)
        os.kill(os.getpid(), signal.SIGHUP)  # (the handler raises at the next instruction)
        return taken

    monkeypatch.setattr(claims, "_take_claim", signalled)
    with pytest.raises(KeyboardInterrupt), cli_signals.signals(), claims.claimed(tmp_path / "r"):
        pass
    assert sorted(p.name for p in tmp_path.iterdir()) == [] and not claims.holding()
