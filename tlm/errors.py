"""Errors that reach the user.

`InputError` is raised for anything the user wrote wrong: a config, a scene file, a
mesh, a command-line value. The command line catches it, prints its one-line message
and exits with status 2; it never shows a traceback. The message always names the
file, the key and the offending value, so that the line alone says what to fix.
"""

from __future__ import annotations

import difflib
from collections.abc import Iterable


class InputError(ValueError):
    """Bad user input: one line naming the file, the key and the value."""

    def __init__(self, message: str, *, source: str | None = None, key: str | None = None):
        self.source = source
        self.key = key
        where = ""
        if source:
            where = f"{source}: "
        if key:
            where += f"{key}: "
        super().__init__(f"{where}{message}")


def did_you_mean(word: str, choices: Iterable[str]) -> str:
    """Return ' (did you mean X?)' when a close match exists, else ''."""
    close = difflib.get_close_matches(word, list(choices), n=1, cutoff=0.6)
    return f" (did you mean {close[0]!r}?)" if close else ""
