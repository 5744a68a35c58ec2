"""The matplotlib figures a report module saves, kept for a test to look at."""

from __future__ import annotations


def capture(monkeypatch, module) -> list:
    """Every matplotlib figure ``module`` saves (through its ``save``), in order, and still saved."""
    figs = []
    real = module.save

    def keep(fig, *a, **k):
        figs.append(fig)
        return real(fig, *a, **k)

    monkeypatch.setattr(module, "save", keep)
    return figs
