"""A traceback file of an error whose message holds a surrogate (a path of bytes that are not UTF-8, as
``os.fsdecode`` gives it under a UTF-8 locale) is written, the byte escaped: it was lost (UnicodeEncodeError,
so the line named no file). The byte is written ``\\xe8``, as stderr, stdout and a CSV cell show it (h352: it was
Python's ``\\udce8``)."""

from __future__ import annotations

import os

from tlm import cli_signals


def test_a_traceback_naming_a_path_not_utf8_is_saved_with_the_byte_escaped(cache):
    name = os.fsdecode(b"/data/sc\xe8ne.obj")  # (a Latin-1 folder name: a lone surrogate, \udce8)
    try:
        raise FileNotFoundError(f"cannot read {name}")
    except FileNotFoundError as e:
        saved = cli_signals.save_traceback(e)
    assert saved is not None and saved.parent == cache / "tracebacks"
    assert "cannot read /data/sc\\xe8ne.obj" in saved.read_text(encoding="utf-8")  # (as stderr, stdout show it: h352)
