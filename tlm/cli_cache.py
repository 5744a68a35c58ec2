"""``tlm cache [info | list | prune | clear]``: what tlm's caches hold (each entry, ``list``), and their entries
removed whole (:mod:`tlm.cache_admin`); :func:`add_cache_parser` is :func:`tlm.cli.build_parser`'s."""

from __future__ import annotations

import argparse
import json
import sys
import time

from tlm import cache_admin as ca
from tlm.caches import cache_home
from tlm.errors import InputError

_LAST_USE = ("Last use: the latest access or modification time of an entry's files (tlm's read of a frame, a "
             "mesh or normals entry, a scene's remembered fingerprint, a reference or a ground truth refreshes "
             "it; numba's read of a kernel only where the file system keeps access times)")


_STALE = ("a frame is stale where other code than this tlm's wrote it (its sidecar's code_fingerprint is not this "
          "code's, or it has none): its key, which hashes the code, is one this code never reads (another checkout "
          "or version of tlm sharing the cache may)")
_SORTS = ("what", "use", "size")
_PARTIALS_SHOWN = 10  # (tlm cache: a line each for the first partials, references/<key>.partial.npz)


def _out(line: str) -> None:
    """A line of the command's output on stdout (ruff's T20 is for tlm/cli.py's prints alone)."""
    sys.stdout.write(line + "\n")


def _typed(read):
    """An argparse type of a :mod:`tlm.cache_admin` reader: its InputError as argparse's one line."""
    def typed(text: str):
        try:
            return read(text, key="")
        except InputError as e:
            raise argparse.ArgumentTypeError(str(e).removeprefix(": ")) from None
    typed.__name__ = read.__name__
    return typed


def _cache_option(p: argparse.ArgumentParser, default=None, dest: str = "cache") -> None:
    """``--cache``; a command's (``dest`` ``cache_too``) is taken with ``tlm cache``'s, not instead of it."""
    p.add_argument("--cache", action="append", metavar="NAME", default=default, type=_typed(_one_name), dest=dest,
                   help=f"only this cache ({', '.join(ca.NAMES)}); may be given again, before or after the "
                   "command (default: all)")


def _json_option(p: argparse.ArgumentParser, default=False) -> None:
    p.add_argument("--json", action="store_true", default=default,
                   help="as JSON (info: the table; list: a row per entry; prune, clear: what tlm.prune_cache "
                   "returns)")


def _one_name(text: str, key: str = "--cache") -> str:
    return ca.cache_names([text], key)[0]


def add_cache_parser(sub) -> None:
    """``tlm cache`` and its commands, on the subcommands ``sub`` of :func:`tlm.cli.build_parser`."""
    c = sub.add_parser("cache", help="what tlm's caches hold (tlm cache), and old entries removed "
                       "(tlm cache prune, tlm cache clear)",
                       description="What tlm's caches hold, and their old entries removed, whole. " + _LAST_USE
                       + ". Sizes: the apparent bytes of the entries' files (ls -l's, not du's blocks; a folder "
                       "itself counts nothing).")
    _json_option(c)
    _cache_option(c)
    cs = c.add_subparsers(dest="cache_cmd", metavar="{info,list,prune,clear}")
    i = cs.add_parser("info", help="one row per cache: its entries, size, oldest and newest last use, folder, and "
                      "how many frames are stale (what tlm cache alone prints)")
    _json_option(i, argparse.SUPPRESS)
    _cache_option(i, argparse.SUPPRESS, "cache_too")
    ls = cs.add_parser("list", help="one row per entry: what it is (a frame's scene, resolution and mode; a "
                       "reference's resolution, photons and rounds), size, last use, stale or not",
                       description="One row per entry: what it is (kind; a frame's scene, resolution and mode, from "
                       "its sidecar, and where frames of the same differ, the settings their sidecars record that "
                       "they differ in, [spp=2 filter=knn], else other= and the start of each's key; a reference's or "
                       "ground truth's resolution, photons and rounds or spp, from its meta.json and image), its size, "
                       "last use, and whether it is stale: " + _STALE + ". " + _LAST_USE
                       + ". Listing is no use: no last use changes.")
    ls.add_argument("--sort", choices=_SORTS, default="what", help="what: by cache, then what the entry is, newest "
                    "use first (default); use: least recently used first (as a prune takes them); size: largest "
                    "first")
    ls.add_argument("--stale", action="store_true", help="only the stale frames")
    _json_option(ls, argparse.SUPPRESS)
    _cache_option(ls, argparse.SUPPRESS, "cache_too")
    p = cs.add_parser("prune", help="remove whole entries: the stale frames (--stale), those last used before "
                      "--older-than, then the least recently used until the rest fit --max-size",
                      description=_LAST_USE + ". " + _STALE[0].upper() + _STALE[1:] + ". Never removed: "
                      "files that are not tlm's entries, and writes in progress (a temporary file under an hour "
                      "old, or one a live process is writing). A run that needs a removed entry computes it again.")
    p.add_argument("--stale", action="store_true", help="remove the stale frames: those written by other code "
                   "than this tlm's (tlm cache list --stale lists them)")
    p.add_argument("--older-than", type=_typed(ca.duration), metavar="DURATION",
                   help="remove entries last used more than this long ago: a number and s, m, h, d or w, any "
                   "case (30d, 12h, 90m: minutes, 2w; at most 1000 years)")
    p.add_argument("--max-size", type=_typed(ca.size), metavar="SIZE",
                   help="then the least recently used until the chosen caches' entries take at most this "
                   "(apparent bytes of their files, not du's blocks): bytes, or a number and K, M, G or T, "
                   "powers of 1024, any case, B or iB after it or not (500M, 2G, 2gb, 1.5GiB; at most 1 EiB)")
    _cache_option(p, argparse.SUPPRESS, "cache_too")
    _json_option(p, argparse.SUPPRESS)
    p.add_argument("--dry-run", action="store_true", help="list what would go, what each is, with sizes; remove "
                   "nothing")
    cl = cs.add_parser("clear", help="remove every entry of the caches (--cache: of those only)")
    _cache_option(cl, argparse.SUPPRESS, "cache_too")
    _json_option(cl, argparse.SUPPRESS)
    cl.add_argument("--dry-run", action="store_true", help="list what would go, with sizes; remove nothing")
    c.set_defaults(func=cache_command)


def cache_command(args: argparse.Namespace) -> int:
    """``tlm cache``'s handler: its exit status (1 where an entry could not be removed)."""
    given = (getattr(args, "cache", None) or []) + (getattr(args, "cache_too", None) or [])
    names = ca.cache_names(given or None)
    command = getattr(args, "cache_cmd", None) or "info"
    as_json = getattr(args, "json", False)
    if command == "info":
        return _info(names, as_json)
    if command == "list":
        return _list(names, as_json, args.sort, args.stale)
    stale = getattr(args, "stale", False)
    if command == "prune" and args.older_than is None and args.max_size is None and not stale:
        raise InputError("give --older-than DURATION and/or --max-size SIZE, or --stale (tlm cache clear removes "
                         "every entry)", source="tlm cache prune")
    clear = command == "clear"
    try:
        outcome = ca.prune(names, None if clear else args.older_than, None if clear else args.max_size, clear=clear,
                           dry_run=args.dry_run, stale=stale)
    except KeyboardInterrupt as e:  # (Ctrl-C, SIGTERM: still 130 / 143, its line saying what went by then: the
        # rest of it, as tlm.cli_signals.Interrupted's ``kept``, which tlm.cli_failed.exit_status reads)
        if not args.dry_run and getattr(e, "kept", None) is None:
            done = e.removed if isinstance(e, ca.RemovalInterrupted) else []  # (none: before the removal began)
            e.kept = (f"while {'clearing' if clear else 'pruning'} the cache: removed {_count(done)} "
                      f"({ca.human(sum(x.size for x in done))}) before the interrupt")
        raise
    used = [e for e, why in outcome.failed if why == ca.USED]
    failed = [(e, why) for e, why in outcome.failed if why != ca.USED]
    if as_json:
        _out(json.dumps(outcome.record(), indent=1))
        return 1 if failed else 0
    kept = outcome.kept
    kept_size = sum(e.size for e in kept)
    skipped = _skipped(outcome.caches)
    if args.dry_run:
        chosen = outcome.chosen
        for e in chosen:
            _out(f"would remove {e.shown()} ({_described(e)}; {ca.human(e.size)}, last used {_when(e.last_use)}"
                 + (f"; partial: {e.partial})" if e.partial else ")"))
        _out(f"would remove {_count(chosen)} ({ca.human(sum(e.size for e in chosen))}), keep {len(kept)} "
             f"({ca.human(kept_size)}){skipped}; nothing removed (--dry-run)")
        return 0
    done = outcome.removed
    _out(f"removed {_count(done)} ({ca.human(sum(e.size for e in done))}) from {_where(done)}{_partials(done)}, "
         f"kept {len(kept)} "
         f"({ca.human(kept_size)}){skipped}" + (f"; {len(used)} used meanwhile kept" if used else ""))
    if failed:
        e, why = failed[0]
        _out(f"could not remove {_count([x for x, _ in failed])} ({ca.human(sum(x.size for x, _ in failed))}) "
             f"(kept), e.g. {e.shown()}: {why}")
        return 1
    return 0


def _partials(entries: list) -> str:
    """What of ``entries`` are partials (a reference's saved rounds: :func:`tlm.cache_admin.partial_state`), where
    any are: `` (1 partial: 24 rounds saved by an interrupted compute)``."""
    partials = [e for e in entries if e.partial]
    if not partials:
        return ""
    known = [e for e in partials if e.rounds]
    words = [f"{sum(e.rounds for e in known)} rounds saved by "
             + ("an interrupted compute" if len(known) == 1 else "interrupted computes")] if known else []
    if len(known) < len(partials):
        words.append(f"{len(partials) - len(known)} unreadable")
    return f" ({len(partials)} partial{'' if len(partials) == 1 else 's'}: {', '.join(words)})"


def _unjudged(entries: list) -> str:
    """``; 3 not judged: ...``, where frames of another user's were not read (:func:`tlm.cache_look.peek`)."""
    n = sum(e.kind == "frame" and e.stale is None for e in entries)
    return (f"; {n} not judged: {'a frame' if n == 1 else 'frames'} of another user's, not read (a read would mark "
            f"{'it' if n == 1 else 'them'} used now, which only the owner may set back)") if n else ""


def _described(e) -> str:
    """What the entry ``e`` is, in words, ``, stale`` after a stale frame's: ``frame cornell 320x240 pmap, stale``."""
    return e.what() + (", stale" if e.stale else "")


def _count(entries: list) -> str:
    return f"{len(entries)} entr{'y' if len(entries) == 1 else 'ies'}"


def _where(entries: list) -> str:
    names = [n for n in ca.NAMES if any(e.cache == n for e in entries)]
    return ", ".join(names) if names else "no cache"


def _skipped(caches: list, said: str = "left alone") -> str:
    """What a prune or clear never touches (``said``: what to call it), where there is any."""
    busy, other = sum(len(c.busy) for c in caches), sum(len(c.other) for c in caches)
    words = []
    if busy:
        words.append(f"{busy} being written")
    if other:
        words.append(f"{other} not tlm's")
    return f"; {said}: {', '.join(words)}" if words else ""


def _when(t: float | None) -> str:
    return "-" if t is None else time.strftime("%Y-%m-%d %H:%M", time.localtime(t))


def _info(names: list[str], as_json: bool) -> int:
    home = cache_home()
    caches = ca.survey(names, home)
    if as_json:
        _out(ca.as_json(caches, home))
        return 0
    _out(f"tlm's caches in {home}" + (f" ({problem})" if (problem := ca.dangling(home)) else ""))
    rows = [("cache", "entries", "size", "oldest use", "newest use", "folder")]
    for c in caches:
        uses = [e.last_use for e in c.entries]
        rows.append((c.name, str(len(c.entries)), ca.human(c.size), _when(min(uses) if uses else None),
                     _when(max(uses) if uses else None), str(c.folder)))
    every = [e.last_use for c in caches for e in c.entries]
    rows.append(("all", str(sum(len(c.entries) for c in caches)), ca.human(sum(c.size for c in caches)),
                 _when(min(every) if every else None), _when(max(every) if every else None), str(home)))
    widths = [max(len(r[k]) for r in rows) for k in range(6)]
    for r in rows:
        _out("  ".join(v.rjust(w) if k in (1, 2) else v.ljust(w) for k, (v, w) in enumerate(zip(r, widths)))
             .rstrip())
    partials = [e for c in caches for e in c.partials]
    for e in partials[:_PARTIALS_SHOWN]:
        _out(f"{e.shown()}: partial: {e.partial} ({ca.human(e.size)}, last used {_when(e.last_use)})")
    if len(partials) > _PARTIALS_SHOWN:
        _out(f"and {len(partials) - _PARTIALS_SHOWN} partials more (tlm cache --json lists them)")
    for c in caches:
        if c.problem:
            _out(f"{c.name}: {c.problem}: no entries are read there, nor written")
        if c.name == "functional" and c.entries:
            stale = [e for e in c.entries if e.stale]
            _out(f"functional: {len(stale)} of {_count(c.entries)} stale ({ca.human(sum(e.size for e in stale))} of "
                 f"{ca.human(c.size)}): frames of other code than this tlm's, which it never reads"
                 + ("; tlm cache list --stale lists them, tlm cache prune --stale removes them" if stale else "")
                 + _unjudged(c.entries))
    busy = [c for c in caches if c.busy]
    other = [p for c in caches for p in c.other]
    line = f"the folder in all: {ca.human(ca.folder_size(home))}"
    if busy:
        n = sum(len(c.busy) for c in busy)
        line += (f"; being written: {n} file{'' if n == 1 else 's'} "
                 f"({ca.human(sum(c.busy_size for c in busy))})")
    if other:
        line += (f"; not tlm's entries, never removed: {len(other)} "
                 f"({ca.human(sum(c.other_size for c in caches))}), e.g. {other[0]}")
    _out(line)
    _out(_LAST_USE)
    return 0


def _list(names: list[str], as_json: bool, sort: str, stale: bool) -> int:
    """``tlm cache list``: a row per entry of the caches ``names`` (``stale``: the stale frames alone), sorted."""
    home = cache_home()
    caches = ca.survey(names, home, whole=True)
    ca.tell_apart([e for c in caches for e in c.entries])  # (among every frame: the same words with --stale)
    entries = [e for c in caches for e in c.entries if e.stale or not stale]
    entries.sort(key=lambda e: -e.last_use)  # (then stably: newest use first within what is alike)
    if sort == "what":
        entries.sort(key=lambda e: (ca.NAMES.index(e.cache), e.kind, str(e.about.get("scene", "")),
                                    e.about.get("resolution", [0, 0]), str(e.about.get("mode", ""))))
    else:
        entries.sort(key=lambda e: e.last_use if sort == "use" else -e.size)
    if as_json:
        _out(json.dumps({"folder": str(home), "code_fingerprint": ca.code_fingerprint(), "sort": sort,
                         "problems": [p for p in [ca.dangling(home), *(c.problem for c in caches)] if p],
                         "entries": [e.row() for e in entries]}, indent=1))
        return 0
    _out(f"tlm's cache entries in {home} (this tlm's code: {ca.code_fingerprint()})")
    rows = [("entry", "what", "size", "last use", "stale")] + [
        (e.shown(), e.what(), ca.human(e.size), _when(e.last_use),
         "stale" if e.stale else "not judged" if e.kind == "frame" and e.stale is None else "") for e in entries]
    widths = [max(len(r[k]) for r in rows) for k in range(5)]
    for r in rows:
        _out("  ".join(v.rjust(w) if k == 2 else v.ljust(w) for k, (v, w) in enumerate(zip(r, widths))).rstrip())
    old = [e for e in entries if e.stale]
    _out(f"{_count(entries)} ({ca.human(sum(e.size for e in entries))}), {len(old)} stale "
         f"({ca.human(sum(e.size for e in old))}){_unjudged(entries)}{_skipped(caches, 'not entries')}")
    for p in [ca.dangling(home), *(c.problem for c in caches)]:
        if p:
            _out(p)
    _out(_STALE[0].upper() + _STALE[1:] + "; tlm cache prune --stale removes them")
    return 0
