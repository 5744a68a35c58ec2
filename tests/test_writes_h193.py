"""A run's host-side writes: trace.json spelt out slice by slice, the .npz files at zlib level 1.

``Trace.write`` writes the text ``json.dumps`` makes of the trace's document (strict: a float
that is not finite as null), byte for byte, but spells each slice's event itself rather than
making its dict and dumping it (:func:`tlm.storage.json_text` is called for the rows' metadata
and the document's other keys only). ``save_npz`` writes what ``np.savez_compressed`` writes,
at zlib level 1: the same arrays read back.
"""

from __future__ import annotations

import json
import math
import zipfile
import zlib

import numpy as np
import pytest

import tlm.arch.units as units
from tlm.arch.functional import Functional, save_npz
from tlm.arch.units import Trace
from tlm.config import config_from_dict
from tlm.experiments.run import programs_for, render, simulate_render, write_run
from tlm.storage import json_text


def expected(trace: Trace, hz) -> bytes:
    """The old writer's text: ``json_text`` of the document (what it wrote, event by event)."""
    return json_text(trace.to_json(hz)).encode()


def written(trace: Trace, hz, path, monkeypatch) -> tuple[bytes, int]:
    """``trace.write``'s bytes, and how many times it called ``json_text``."""
    calls = []

    def counted(value, **kw):
        calls.append(1)
        return json_text(value, **kw)

    with monkeypatch.context() as m:
        m.setattr(units, "json_text", counted)
        trace.write(path, hz)
    return path.read_bytes(), len(calls)


@pytest.fixture(scope="module", params=["rcast", "pmap"])
def ran(request, tmp_path_factory):
    """A Cornell frame of each mode on two pipelines, simulated (5,000 slices in packets of 4
    rays, 16,000 of a photon-map frame in its own) and written with its trace and AOVs."""
    arch = {"pipelines": 2, **({"packet_size": 4} if request.param == "rcast" else {})}
    cfg = config_from_dict({"scene": "cornell", "mode": request.param, "resolution": [24, 24],
                            "render": {"spp": 1}, "arch": arch}, "test")
    res = simulate_render(render(cfg), programs_for(cfg, None))
    out = tmp_path_factory.mktemp(request.param) / "run"
    write_run(res, out, outputs=("trace", "aov"))
    return res, out


def test_a_run_s_trace_json_is_the_document_s_text_spelt_without_dumping_each_event(ran, tmp_path, monkeypatch):
    """The run folder's trace.json, and the trace written again at both clocks (slices unread
    and then read, their args dicts made): byte for byte ``json_text`` of the document, with
    json_text called only for the rows' metadata and the two other keys, not once a slice."""
    res, out = ran
    trace, hz = res.timing.trace, res.cfg.arch.clock_hz
    flat = list(trace._flat)  # (before anything reads the slices: the work slices' args not made yet)
    assert None in flat[4::8]
    assert len(trace.events) > 500 and len(trace.rows) > 10  # (two pipelines: their PMs, modules, compose)
    metadata = 2 * len(trace.rows) + 2
    for clock in (hz, None, 1.0, 3.0):
        fresh = Trace()
        fresh.__dict__.update(trace.__dict__, _flat=list(flat))  # (work slices not read yet)
        first, calls = written(fresh, clock, tmp_path / "a.json", monkeypatch)
        assert calls == metadata, (clock, calls)
        want = expected(fresh, clock)  # (reads the slices: each work slice's args a dict now)
        again, _ = written(fresh, clock, tmp_path / "b.json", monkeypatch)
        assert first == want and again == want, clock
    assert (out / "trace.json").read_bytes() == expected(trace, hz)
    assert len(json.loads((out / "trace.json").read_text())["traceEvents"]) == len(trace.events) + 2 * len(trace.rows)


EDGE_FLOATS = [0.0, -0.0, 0.1 + 0.2, 1 / 3, 1e16, 1e15 + 0.5, 9007199254740993.0, 1e-4, 1e-5, 5e-324, 2.5e-308,
               1.7976931348623157e308, -123.456, 1e22, math.inf, -math.inf, math.nan]
EDGE_INTS = [0, -1, 2**53 + 1, 2**64, -(2**70), 10**30]
EDGE_WORDS = ["", "plain", 'a "quoted" \\ back\\slash', "tab\tnew\nline\x00\x1f", "caf\u00e9 \u2028 \u20ac",
              "\U0001f600", "\ud800"]


def edge_trace(trace: Trace | None = None) -> Trace:
    """Slices of every kind of arg the writer spells: ints, floats (not finite too), strings
    that json.dumps escapes, bools and None; names and keys to escape; cycles up to 2**60
    (added to ``trace``, else to a new one)."""
    trace = Trace() if trace is None else trace
    t = 0
    for k, v in enumerate([*EDGE_FLOATS, *EDGE_INTS, *(f"[{w}]" for w in EDGE_WORDS), True, False, None]):
        trace.slice(f"pipe{k % 2}.traversal", EDGE_WORDS[k % len(EDGE_WORDS)] or "busy", t, t + k + 1,
                    **{f"{EDGE_WORDS[(k + 1) % len(EDGE_WORDS)]}:": v, "n": k})
        t += k + 1
    trace.slice("mem0", "work", 2**60, 2**60 + 7, T_norm=5, T_ms=0, T_ps=2)
    trace.slice("mem1", "empty", 3, 2**53 + 3)  # (no args: idle's {})
    unit_rows = {"pipe0.fragment": trace.row("pipe0.fragment")}
    trace.add_work(unit_rows["pipe0.fragment"], "busy", 0, 10**6 + 7, 10**6, 5, 2)  # (an unread work slice)
    return trace


@pytest.mark.parametrize("clock", [None, 600e6, 1.0, 3.0, 7e9, 1e300, math.inf, 600000000])
def test_edge_values_are_written_as_json_dumps_writes_them(tmp_path, monkeypatch, clock):
    """Every number and string as ``json.dumps`` has it (``float.__repr__``, ``int.__repr__``,
    ASCII with escapes), a float arg that is not finite as null; all spelt by the writer itself."""
    trace = edge_trace()
    text, calls = written(trace, clock, tmp_path / "t.json", monkeypatch)
    assert calls == 2 * len(trace.rows) + 2
    assert text == expected(trace, clock)
    assert "Infinity" not in text.decode() and "NaN" not in text.decode()
    doc = json.loads(text)
    args = [e["args"] for e in doc["traceEvents"] if e["ph"] == "X"]
    assert [a[next(iter(a))] for a in args[:len(EDGE_FLOATS) - 3]] == EDGE_FLOATS[:-3]
    assert all(a[next(iter(a))] is None for a in args[len(EDGE_FLOATS) - 3:len(EDGE_FLOATS)])


@pytest.mark.parametrize("clock", [1e-300, math.nan, -2.5e6])
def test_a_clock_that_puts_a_slice_at_no_finite_time_writes_no_trace(tmp_path, clock):
    """A time past the float range (a tiny clock), a NaN or a negative clock: no trace.json with null or
    negative timestamps (it was written, and Perfetto could not read it), a ValueError naming the clock
    (arch.clock_hz is at least 1 Hz: tests/test_arch_bounds_h212.py)."""
    with pytest.raises(ValueError, match="clock_hz"):
        edge_trace().write(tmp_path / "t.json", clock)
    assert not (tmp_path / "t.json").exists() and list(tmp_path.iterdir()) == []


def test_what_the_writer_does_not_spell_is_json_text_s(tmp_path, monkeypatch):
    """A slice's own ``start_cycle`` arg (the event's replaces it in place), a numpy number, a
    nested arg, a non-str key, a str subclass's name: json_text writes them, the same text (the
    slices of that one's chunk of 4,096, the others still spelt out); an arg json.dumps refuses
    is still refused."""
    class Word(str):
        pass

    for odd in [{"start_cycle": 1, "a": 2}, {"cycles": 3}, {"f": np.float64(0.1)}, {"list": [1, 2.5]},
                {"d": {"k": math.inf}}, {1: "int key"}]:
        trace = Trace()
        for k in range(4096):  # (the first chunk)
            trace.add_work(trace.row("pipe0.vertex"), "busy", 2 * k, 2 * k + 1, k, 1, 0)
        edge_trace(trace)
        trace.add(trace.row("xbar"), "odd", 5, 9, odd)
        text, calls = written(trace, 600e6, tmp_path / "t.json", monkeypatch)
        assert text == expected(trace, 600e6), odd
        assert calls == 2 * len(trace.rows) + 2 + len(trace.events) - 4096, odd  # (the second chunk's slices)
    trace = Trace()
    trace.slice("xbar", Word("grant"), 0, 4)
    assert written(trace, None, tmp_path / "t.json", monkeypatch)[0] == expected(trace, None)
    trace.slice("xbar", "bad", 4, 8, n=np.int64(3))
    with pytest.raises(TypeError, match="int64"):
        trace.write(tmp_path / "t.json", None)


@pytest.mark.parametrize("n", [4095, 4096, 4097, 8193])
def test_chunk_seams(tmp_path, monkeypatch, n):
    """Slices 4,096 at a time: the seams joined as one list."""
    trace = Trace()
    for k in range(n):
        trace.add_work(trace.row(f"pipe{k % 3}.vertex"), "busy", 2 * k, 2 * k + 1, k, 1, 0)
    text, calls = written(trace, 600e6, tmp_path / "t.json", monkeypatch)
    assert text == expected(trace, 600e6)
    assert calls == 2 * 3 + 2


def member_levels(path) -> set[int]:
    """The zlib levels, of 1 and 6 (savez_compressed's), at which deflating each member's bytes
    gives the member as stored in ``path`` (those of every member that tells them apart)."""
    levels = {1, 6}
    told = 0
    with zipfile.ZipFile(path) as zf, open(path, "rb") as fh:
        for info in zf.infolist():
            fh.seek(info.header_offset)
            head = fh.read(30)  # (the local header: the name's and extra field's lengths at 26 and 28)
            fh.seek(info.header_offset + 30 + int.from_bytes(head[26:28], "little") + int.from_bytes(head[28:30],
                                                                                                    "little"))
            stored, raw = fh.read(info.compress_size), zf.read(info)
            deflated = {lv: c.compress(raw) + c.flush()
                        for lv, c in ((lv, zlib.compressobj(lv, zlib.DEFLATED, -15)) for lv in (1, 6))}
            if deflated[1] != deflated[6]:
                told += 1
                levels &= {lv for lv, data in deflated.items() if data == stored}
    assert told, path
    return levels


def test_a_run_s_aov_files_are_deflated_at_level_1_and_load_as_before(ran, tmp_path):
    """aov/primary.npz and aov/work.npz: the arrays savez_compressed would have written (names,
    dtypes, shapes, values; np.load without pickles), each member deflated at level 1."""
    res, out = ran
    h, w = res.scene.camera.height, res.scene.camera.width
    p = res.primary
    want = {"primary": {"origin": p.origin.reshape(h, w, 3), "direction": p.direction.reshape(h, w, 3),
                        "t": p.t.reshape(h, w), "triangle": p.triangle.reshape(h, w),
                        "normal": p.normal.reshape(h, w, 3)},
            "work": {f"{q}.{k}": v for q, counts in res.work.items() for k, v in counts.items()}}
    for name, arrays in want.items():
        np.savez_compressed(tmp_path / f"{name}.npz", **arrays)
        with np.load(out / "aov" / f"{name}.npz", allow_pickle=False) as got, \
                np.load(tmp_path / f"{name}.npz", allow_pickle=False) as old:
            assert got.files == old.files == list(arrays)
            for k in got.files:
                a, b = got[k], old[k]
                assert a.dtype == b.dtype and a.shape == b.shape and np.array_equal(a, b, equal_nan=True), (name, k)
    assert member_levels(out / "aov" / "work.npz") == {1}


def test_a_functional_entry_is_deflated_at_level_1_and_loads_the_same(ran, tmp_path):
    res, _ = ran
    fn = res.functional()
    fn.save(tmp_path / "f.npz")
    assert Functional.load(tmp_path / "f.npz") == fn
    assert member_levels(tmp_path / "f.npz") == {1}


def test_save_npz_is_savez_compressed_s_arrays(tmp_path):
    """Any dtype and shape (0-d, empty, Fortran order, big-endian, structured), into a path or
    an open file; an object array refused (no pickles)."""
    rng = np.random.default_rng(0)
    arrays = {"f32": rng.random((7, 5), dtype=np.float32), "i64": np.arange(-5, 10**5, 7),
              "scalar": np.array(3.5), "empty": np.zeros((0, 3), np.int16), "fortran": np.asfortranarray(
                  rng.random((4, 6))), "be": np.arange(6, dtype=">u4"), "bool": rng.random(9) > 0.5,
              "rec": np.array([(1, 2.0)], dtype=[("a", "<i4"), ("b", "<f8")]), "work/pass/x": np.ones(3, np.uint8)}
    save_npz(tmp_path / "a.npz", arrays)
    with open(tmp_path / "b.npz", "wb") as fh:
        save_npz(fh, arrays)
    np.savez_compressed(tmp_path / "c.npz", **arrays)
    for f in ("a.npz", "b.npz"):
        with np.load(tmp_path / f, allow_pickle=False) as got, np.load(tmp_path / "c.npz") as old:
            assert got.files == old.files
            for k in got.files:
                a, b = got[k], old[k]
                assert a.dtype == b.dtype and a.shape == b.shape and np.array_equal(a, b), k
                assert a.flags.f_contiguous == b.flags.f_contiguous, k
    with pytest.raises(ValueError, match="pickle"):
        save_npz(tmp_path / "d.npz", {"o": np.array([{}, None], dtype=object)})
