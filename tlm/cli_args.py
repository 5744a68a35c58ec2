"""The command line's argument types and the options several commands share: the parser with
the project's one-line error (a command's naming the command), a folder's or a table's path
checked as argparse reads it, and ``--no-report``, ``--formats``, ``--dpi``, ``--no-progress``
(:func:`tlm.cli.build_parser`)."""

from __future__ import annotations

import argparse
from pathlib import Path

from tlm.api import InputError


class _Once(argparse._StoreAction):
    """A flag of one value (``--mode``, ``--seed``, ``--out``): given twice in one command it is
    refused, naming both values (``--mode given twice (rcast, then pmap): give it once``), not
    taken as the last (argparse's way, which drops the first silently). A flag that gathers its
    values (``--set``: ``action="append"``) is not one."""

    def __call__(self, parser, namespace, values, option_string=None):
        given = namespace.__dict__.setdefault(_GIVEN, {})
        if self.dest in given:
            first_flag, first = given[self.dest]
            flag = first_flag if first_flag == option_string else f"{first_flag} (then {option_string})"
            parser.error(f"{flag} given twice ({first}, then {values}): give it once")
        given[self.dest] = (option_string, values)
        super().__call__(parser, namespace, values, option_string)


_GIVEN = "_tlm_flags_given"  # (the namespace's record of the one-value flags given, while it is parsed)


class Parser(argparse.ArgumentParser):
    """argparse with the project's one-line error and exit status 2: ``tlm: error: MESSAGE``
    (the top-level parser: the line names ``tlm`` once); a flag of one value given twice is
    refused (:class:`_Once`)."""

    def error(self, message: str):  # type: ignore[override]
        raise InputError(message.replace("\n", " "))

    def add_argument(self, *args, **kwargs):
        if args and args[0].startswith(self.prefix_chars) and kwargs.get("action", "store") == "store" \
                and kwargs.get("nargs") in (None, "?"):
            kwargs["action"] = _Once
        return super().add_argument(*args, **kwargs)

    def parse_known_args(self, args=None, namespace=None):
        parsed, extras = super().parse_known_args(args, namespace)
        parsed.__dict__.pop(_GIVEN, None)
        return parsed, extras

    def add_subparsers(self, **kwargs):
        kwargs.setdefault("parser_class", Subcommand)
        return super().add_subparsers(**kwargs)


class Subcommand(Parser):
    """A command's parser (``tlm granularity``, ``tlm scene list``): its errors name it, and an
    argument it does not know is its error, ``tlm: error: tlm granularity: unrecognized
    arguments: --x``, not left over for the top-level parser (which would name no command)."""

    def error(self, message: str):  # type: ignore[override]
        raise InputError(message.replace("\n", " "), source=self.prog)

    def parse_known_args(self, args=None, namespace=None):
        parsed, extras = super().parse_known_args(args, namespace)
        if extras:
            self.error(f"unrecognized arguments: {' '.join(extras)}")
        return parsed, extras


class _AsTyped(float):
    """A number read from the command line that reads back as the user typed it (``-3``,
    not ``-3.0``): an error that names the value echoes the argument given."""

    text: str

    def __new__(cls, text: str) -> _AsTyped:
        number = super().__new__(cls, text)
        number.text = text.strip()
        return number

    def __repr__(self) -> str:
        return self.text

    __str__ = __repr__


def seconds(text: str) -> float:
    """``sweep --dask-wait``: a number of seconds, as typed (the sweep checks that it is a wait)."""
    try:
        return _AsTyped(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number of seconds") from None


def folder_name(text: str) -> str:
    """``--out``: a folder's path; an empty one is refused (not read as the default)."""
    if not text.strip():
        raise argparse.ArgumentTypeError("an empty path names no folder (leave --out out for the default)")
    return text


def title(text: str) -> str:
    """``report --title``: a title with something in it (an empty one was the default's)."""
    if not text.strip():
        raise argparse.ArgumentTypeError("an empty title: give one, or leave --title out for the default")
    return text


def table_file(text: str) -> str:
    """``calibrate --write``: a table file's path, checked before the fit (a folder, or a
    file in a folder that does not exist, would fail only after it)."""
    if not text.strip():
        raise argparse.ArgumentTypeError("an empty path names no table (leave --write out for the study's own "
                                         "table)")
    path = Path(text)
    if path.is_dir():
        raise argparse.ArgumentTypeError(f"{text} is a folder, not a table file")
    if not path.parent.is_dir():
        raise argparse.ArgumentTypeError(f"the folder of {text} does not exist")
    return text


def figure_files(parser: argparse.ArgumentParser) -> None:
    """``--formats`` and ``--dpi``: the report's figure files (checked before any work:
    :func:`tlm.cli._figure_args`)."""
    parser.add_argument("--formats", metavar="LIST",
                        help="the files each figure of the report is written as, separated by commas: png, pdf, svg "
                        "(default: png; the PNG always, as the page embeds it; a PDF or SVG is beside its PNG, of the "
                        "same stem, and linked from its caption)")
    parser.add_argument("--dpi", metavar="N", help="the report's PNGs' dots per inch, from 50 to 1200 (default: 110)")


def no_report(parser: argparse.ArgumentParser) -> None:
    """``--no-report``, and the report's ``--formats`` and ``--dpi`` (:func:`figure_files`)."""
    parser.add_argument("--no-report", action="store_true", help="do not write OUT/report (see 'tlm report')")
    figure_files(parser)


# --no-progress's help where the command draws no bar: its lines on stdout are its output, kept
NO_BAR = "this command draws none (taken so that a script may pass it to every command; it changes nothing here)"


def no_progress(parser: argparse.ArgumentParser, bars: str | None = None) -> None:
    """``--no-progress``: no progress bar. Every command that runs an experiment or writes a
    report takes it, so that a script may pass it to each. ``bars``: its help where the command
    draws no bar of its own: what it turns off instead (``tlm plots``: its steps' bars), or
    :data:`NO_BAR`, that it changes nothing there."""
    if bars is None:
        what = "no progress bar (none either when stderr is not a terminal)"
    else:
        what = f"no progress bar: {bars}"
    parser.add_argument("--no-progress", action="store_true", help=what)


def experiment_argument(parser: argparse.ArgumentParser, what: str, name: str) -> None:
    """The positional ``config`` of a command that takes an experiment file (``what``): its help names
    the built-in experiment ``name`` first, which runs from any folder, then its file, which a checkout
    alone has (``configs/NAME.yaml``)."""
    parser.add_argument("config", help=f"{what}, or a built-in experiment's name: {name} (from any folder; "
                        f"its file in a checkout: configs/{name}.yaml)")
