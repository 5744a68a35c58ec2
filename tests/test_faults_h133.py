"""Faults left over from the last probe, and the guarded streams' own module.

* Under ``ulimit -v`` of some 420-460 MB a ``tlm run cornell`` ended in OpenBLAS itself
  (``OpenBLAS error: Memory allocation still failed ...``, exit 1): the quad lights' test of the
  shading (:func:`tlm.kernels.shade.emitted`) called ``np.linalg.solve`` (LAPACK's ``dgesv``) and
  ``@`` (``dgemv``) on every batch, and OpenBLAS maps a buffer for each such call under way at
  once on the render's threads. They are written out now (:func:`~tlm.kernels.shade.dot3`,
  :func:`~tlm.kernels.shade.solve2`): the same hits.
* A thread the system refused (``RuntimeError: can't start new thread``: a render's pool under
  ``ulimit -v`` or ``ulimit -u``) was a ``tlm: internal error``; now one line naming the limits.
* A MemoryError in :func:`tlm.cli_signals.forget_lost_interrupt` (``python -m tlm``'s last call)
  escaped as a traceback.
* Under ``ulimit -v``, a library that could not be mapped as it was imported (matplotlib's, for
  the report) was a ``tlm: internal error``; now out of memory.
* The guarded stdout and stderr moved to :mod:`tlm.cli_streams`; their names are still
  :mod:`tlm.cli_signals`' too, and a monkeypatch of them there reaches the code.
"""

from __future__ import annotations

import ast
import inspect
import textwrap

import numpy as np
import pytest

from tlm import cli_failed, cli_signals, cli_streams, errors
from tlm.kernels import shade
from tlm.scenes.loader import load_scene


def test_a_thread_the_system_refused_is_one_line_naming_the_limits(capsys, monkeypatch):
    monkeypatch.setattr(errors, "address_space_limit", lambda: 400 * 2**20)
    assert cli_failed.exit_status(RuntimeError("can't start new thread"), ["run"]) == 1
    err = capsys.readouterr().err
    assert err.startswith("tlm: error: no new thread could be started: can't start new thread (")
    assert "limited to 400 MiB: ulimit -v" in err and "internal" not in err and len(err.splitlines()) == 1
    try:  # (wrapped: a pool's error raised from it)
        try:
            raise RuntimeError("can't start new thread")
        except RuntimeError as inner:
            raise OSError("the pool could not start") from inner
    except OSError as wrapped:
        assert cli_failed.exit_status(wrapped, ["run"]) == 1
    assert capsys.readouterr().err.startswith("tlm: error: no new thread could be started")
    # another RuntimeError is still a bug: its traceback kept
    assert errors.thread_problem(RuntimeError("can't start a car")) is None


def test_a_memory_error_as_python_m_tlm_exits_is_not_a_traceback(monkeypatch):
    def no_memory(source):
        raise MemoryError

    monkeypatch.setattr(cli_signals, "exec", no_memory, raising=False)  # (the module's global: before builtins)
    cli_signals.forget_lost_interrupt()  # (raised MemoryError before)


def test_a_library_not_mapped_under_a_limit_is_out_of_memory(capsys, monkeypatch):
    e = ImportError("libXau-154567c4.so.6.0.0: failed to map segment from shared object")
    monkeypatch.setattr(errors, "address_space_limit", lambda: None)
    assert errors.memory_problem(e) is None  # (no limit set: not memory, as far as tlm can tell)
    monkeypatch.setattr(errors, "address_space_limit", lambda: 600 * 2**20)
    assert cli_failed.exit_status(e, ["run"]) == 1
    err = capsys.readouterr().err
    assert err == ("tlm: error: out of memory: libXau-154567c4.so.6.0.0: failed to map segment from shared object "
                   "(the address space of this process is limited to 600 MiB: ulimit -v)\n")


def _calls(fn) -> set[str]:
    tree = ast.parse(textwrap.dedent(inspect.getsource(fn)))
    matmul = any(isinstance(n, ast.BinOp) and isinstance(n.op, ast.MatMult) for n in ast.walk(tree))
    return {ast.unparse(c.func) for c in ast.walk(tree) if isinstance(c, ast.Call)} | ({"@"} if matmul else set())


def test_the_written_out_solve_and_products_are_blas_up_to_rounding():
    rng = np.random.default_rng(3)
    for _ in range(50):
        a = rng.normal(size=(2, 2))
        r = rng.normal(size=(2, 9))
        x0, x1 = shade.solve2(a, r[0], r[1])
        np.testing.assert_allclose(np.stack([x0, x1]), np.linalg.solve(a, r), rtol=1e-9, atol=1e-12)
        v, w = rng.normal(size=(9, 3)), rng.normal(size=3)
        np.testing.assert_allclose(shade.dot3(v, w), v @ w, rtol=1e-12, atol=1e-14)
    with np.errstate(divide="ignore", invalid="ignore"):  # a singular matrix: no finite coordinates
        x0, x1 = shade.solve2(np.zeros((2, 2)), np.ones(3), np.ones(3))
    assert not np.isfinite(x0).any() and not np.isfinite(x1).any()


def _blas_emitted(lights, o, d, t_hit, eps):
    """HEAD's :func:`tlm.kernels.shade.emitted` (np.linalg.solve and ``@``), for the comparison."""
    k = o.shape[0]
    radiance, seen = np.zeros((k, 3)), np.zeros(k, dtype=bool)
    best = t_hit
    dist_eps = eps / np.linalg.norm(d, axis=1)
    for light in [x for x in lights if x.kind == "quad" and x.area != 0.0]:
        q, nl = light.quad, light.normal
        dn = d @ nl
        with np.errstate(divide="ignore", invalid="ignore"):
            t = ((q.corner - o) @ nl) / dn
        p = o + np.where(np.isfinite(t), t, 0.0)[:, None] * d - q.corner
        a, b = np.linalg.solve(q.gram, np.stack([p @ q.edge_u, p @ q.edge_v]))
        hit = (dn < 0) & (t > dist_eps) & (t <= best + dist_eps) & (a >= 0) & (a <= 1) & (b >= 0) & (b <= 1)
        radiance[hit] = q.radiance
        seen |= hit
        best = np.where(hit, t, best)
    return radiance, seen


@pytest.mark.parametrize("scene", ["cornell", "room"])
def test_the_quad_lights_test_calls_no_blas_and_sees_the_same_rays(scene):
    for fn in (shade.emitted, shade.dot3, shade.solve2):
        used = _calls(fn)
        assert not {c for c in used if c == "@" or "linalg.solve" in c or "matmul" in c or c.endswith("dot")}, used
    s = load_scene(scene)
    rng = np.random.default_rng(4)
    lo, hi = s.triangles.reshape(-1, 3).min(0), s.triangles.reshape(-1, 3).max(0)
    quad = next(x for x in s.lights if x.kind == "quad").quad
    for k in (1, 5, 20000):
        o = lo + rng.random((k, 3)) * (hi - lo)
        ab = rng.uniform(-0.01, 1.01, size=(k, 2))  # (aimed at the light, some just past its edges)
        d = quad.corner + ab[:, :1] * quad.edge_u + ab[:, 1:] * quad.edge_v - o
        d /= np.linalg.norm(d, axis=1, keepdims=True)
        t_hit = np.where(rng.random(k) < 0.5, np.inf, rng.random(k) * 5)
        want, now = _blas_emitted(s.lights, o, d, t_hit, 1e-4), shade.emitted(s.lights, o, d, t_hit, 1e-4)
        assert now[0].tobytes() == want[0].tobytes() and np.array_equal(now[1], want[1])
        assert 0 < now[1].sum() < k or k < 20000


def test_the_guarded_streams_are_imported_by_cli_signals_from_cli_streams():
    for name in ("guard_streams", "writes_files", "no_stream_closed"):
        assert getattr(cli_signals, name) is getattr(cli_streams, name), name
