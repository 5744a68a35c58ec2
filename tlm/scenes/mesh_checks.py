"""The checks of a mesh file's bytes and the files it names that run before trimesh reads it
(out of :mod:`tlm.scenes.meshes`, whose ``_load_trimesh`` calls them by their old private names):
an ASCII STL's facets, a glTF's buffer URIs (absolute ones refused, percent-encoded ones decoded,
missing ones named), a ``.glb``'s BIN chunk, and the resolver that notes each file beside a glTF
that trimesh reads (:func:`tlm.config.noting_reads`). Each problem is an
:class:`~tlm.errors.InputError` naming the file (and, for an STL, the line)."""

from __future__ import annotations

import functools
import re
from pathlib import Path

from tlm.errors import InputError, quoted

__all__ = ["absolute_uri", "buffer_files", "buffer_reader", "check_ascii_stl", "glb_binary", "noting_resolver",
           "noting_resolver_class"]


def absolute_uri(uri: str) -> bool:
    """Whether a glTF ``uri`` is an absolute path or has a scheme (``/etc/x.bin``, ``C:/x.bin``,
    ``http://...``, ``file:///...``): not a file name relative to the glTF, which tlm reads no other
    way (``../bin/x.bin``, a folder up, is relative: read)."""
    return uri.strip().startswith(("/", "\\")) or re.match(r"[A-Za-z][A-Za-z0-9+.-]*:", uri.strip()) is not None


def buffer_files(header: dict, path: Path, src: str) -> list | None:
    """A glTF's ``buffers`` with each file name (``uri``, RFC 3986) percent-decoded where
    the file is there by its decoded name (Blender writes ``my%20model.bin``); None when no
    name changes. An InputError names a buffer whose file is missing, or whose ``uri`` is
    absolute (:func:`absolute_uri`)."""
    from urllib.parse import unquote

    buffers = header.get("buffers")
    if not isinstance(buffers, list):
        return None
    out, changed = [], False
    for i, b in enumerate(buffers):
        uri = b.get("uri") if isinstance(b, dict) else None
        if not isinstance(uri, str) or uri.startswith("data:"):
            out.append(b)
            continue
        if absolute_uri(uri):
            raise InputError(f"buffers[{i}].uri {quoted(uri)} is an absolute path or URL: tlm reads a glTF's buffers "
                             f"from files named relative to its folder, {path.parent} (../ included)", source=src)
        plain = unquote(uri)
        if not (path.parent / uri).is_file() and (path.parent / plain).is_file():
            out.append({**b, "uri": plain})
            changed = True
            continue
        if not (path.parent / uri).is_file():
            raise InputError(f"buffers[{i}].uri {quoted(uri)}: no file {path.parent / plain}", source=src)
        out.append(b)
    return out if changed else None


def buffer_reader(header: dict, path: Path, binary: bytes | None, src: str):
    """``read(i) -> bytes``: the bytes of a glTF's ``buffers[i]`` (a ``.glb``'s first buffer
    without a ``uri`` its BIN chunk ``binary``, a ``data:`` URI decoded, else the file named
    relative to the glTF, by its name or percent-decoded); an InputError names a buffer that
    holds nothing tlm can read."""
    import base64
    import binascii
    from urllib.parse import unquote

    buffers = header.get("buffers") if isinstance(header.get("buffers"), list) else []
    got: dict[int, bytes] = {}  # (each buffer read once: a skin's matrices are read for every node it skins)

    def read(i: int) -> bytes:
        if i not in got:
            got[i] = _read(i)
        return got[i]

    def _read(i: int) -> bytes:
        b = buffers[i] if 0 <= i < len(buffers) and isinstance(buffers[i], dict) else None
        uri = None if b is None else b.get("uri")
        if b is not None and uri is None and binary is not None and i == 0:
            return binary
        if isinstance(uri, str) and uri.startswith("data:"):
            head, _, payload = uri.partition(",")
            try:
                return (base64.b64decode(re.sub(r"\s+", "", payload, flags=re.ASCII), validate=True)
                        if ";base64" in head else unquote(payload).encode("latin-1", "replace"))
            except (binascii.Error, ValueError):
                raise InputError(f"buffers[{i}].uri: its data URI is not valid base64", source=src) from None
        if isinstance(uri, str) and not absolute_uri(uri):
            for f in (path.parent / uri, path.parent / unquote(uri)):
                if f.is_file():
                    return f.read_bytes()
        raise InputError(f"buffers[{i}]: no data tlm can read (a uri relative to the glTF, a data URI, or a .glb's "
                         "BIN chunk)", source=src)

    return read


def glb_binary(data: bytes, ext: str, src: str) -> bytes | None:
    """A ``.glb``'s BIN chunk (b"" if none); None for a ``.gltf``."""
    from tlm.scenes.materials import glb_chunks

    return glb_chunks(data, src)[1] if ext == ".glb" else None


def check_ascii_stl(path: Path, data: bytes | None, src: str) -> None:
    """An ASCII STL's facets each hold 3 vertices (trimesh fails to reshape, or reads on into the
    next facet): an InputError names the first that does not, and its line. A binary STL (its
    length is its header's facet count's) is not checked here (``data``: the bytes, decompressed,
    when they were read already)."""
    if data is None:
        with open(path, "rb") as f:
            head, size = f.read(84), path.stat().st_size
    else:
        head, size = data[:84], len(data)
    if head[:5].lower() != b"solid" or (len(head) == 84 and size == 84 + 50 * int.from_bytes(head[80:84], "little")):
        return
    data = path.read_bytes() if data is None else data
    loops = data.count(b"endloop")
    if data.count(b"vertex") == 3 * loops:  # (the usual file, quickly)
        return
    for k, m in enumerate(re.finditer(rb"outer\s+loop(.*?)endloop", data, re.S)):
        n = len(re.findall(rb"(?<![A-Za-z_])vertex(?![A-Za-z_])", m.group(1)))
        if n != 3:
            line = data.count(b"\n", 0, m.start()) + 1
            raise InputError(f"line {line}: facet {k} (from 0) has {n} vertices: an STL facet is a triangle (3 "
                             "'vertex' lines between 'outer loop' and 'endloop')", source=src)


def noting_resolver(path: str):
    """trimesh's resolver of the files beside ``path`` (``FilePathResolver``, as trimesh makes one for a
    file it loads) that notes each file it reads inside :func:`tlm.config.noting_reads`:
    ``("side", the file, sha256 of the bytes it returned)`` (a glTF's buffers: what the parse read,
    which what remembers the parse checks them by, :func:`tlm.scenes.cache.read_as`)."""
    return noting_resolver_class()(path)


@functools.cache
def noting_resolver_class():
    """The class :func:`noting_resolver` makes (trimesh imported, and the class defined, once)."""
    import hashlib
    import inspect
    import os

    from trimesh.resolvers import FilePathResolver

    from tlm.config import note_read

    # (trimesh 5's FilePathResolver refuses a name up a folder unless allow_anywhere; trimesh 4, which
    # pyproject allows, has no such argument)
    _ANYWHERE = "allow_anywhere" in inspect.signature(FilePathResolver.__init__).parameters

    class NotingResolver(FilePathResolver):
        # (a folder up is a relative URI too, which glTF allows: ``../bin/data.bin``; an absolute one is
        # refused, and named by buffer_files before trimesh reads a buffer)
        def __init__(self, source: str):
            if _ANYWHERE:
                super().__init__(source, allow_anywhere=True)
            else:  # (trimesh 4: no such argument; its get joins any name to the folder, ../ included)
                super().__init__(source)

        def absolute(self, name: str):
            if os.path.isabs(name.strip()):
                raise ValueError(f"{quoted(name)} is an absolute path, not a file name relative to the glTF")
            parent = getattr(super(), "absolute", None)  # (trimesh 4 has none)
            return parent(name) if parent is not None else Path(self.parent) / name.strip()

        def get(self, name: str):
            data = super().get(name)
            # (the file read: the first of the names FilePathResolver.get tries that is there; trimesh 4 has
            # no ``absolute``, and joins the name to the folder)
            absolute = getattr(self, "absolute", None) or (lambda n: Path(self.parent) / n)
            try:
                for candidate in (name.strip(), name.strip().lstrip("/"), os.path.split(name)[-1]):
                    try:
                        file = absolute(candidate)
                    except ValueError:
                        continue
                    if file.exists():
                        note_read(("side", str(file), hashlib.sha256(data).hexdigest(), len(data)))
                        break
            except (AttributeError, OSError, TypeError):
                pass  # (not noted: a memo of the parse finds this file's read missing, and remembers nothing)
            return data

    return NotingResolver
