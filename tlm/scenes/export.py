"""Export a scene's world-space triangles, in triangle-id order, as PLY or OBJ.

The PLY file also carries each face's material index (property ``material``).

Each triangle is written with its own three vertices (no welding), so face ``i`` of
the file is triangle id ``i`` of every AOV and BSP leaf, exactly, and the vertex
positions are the ones the renderer uses.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from tlm.errors import EnvironmentFailure, InputError
from tlm.scenes.model import Scene
from tlm.storage import write_atomic, write_file

FORMATS = (".ply", ".obj")


def export_triangles(scene: Scene, path: Path) -> None:
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in FORMATS:
        raise InputError(f"unsupported format {suffix or '(none)'!r}: use {' or '.join(FORMATS)}",
                         source=str(path))
    tri = scene.triangles
    n = tri.shape[0]
    verts = tri.reshape(-1, 3)
    faces = np.arange(3 * n, dtype=np.int64).reshape(n, 3)
    if not path.parent.is_dir():
        raise InputError(f"folder {str(path.parent)!r} does not exist", source=str(path))
    if path.is_dir():
        raise InputError("is a folder; name a .ply or .obj file", source=str(path))
    try:
        _write(scene, path, suffix, verts, faces)
    except EnvironmentFailure:
        raise
    except OSError as e:  # (a folder that takes no files: /proc, a special file system)
        raise EnvironmentFailure(f"cannot write it ({e.strerror or e})", source=str(path)) from None


def _write(scene: Scene, path: Path, suffix: str, verts: np.ndarray, faces: np.ndarray) -> None:
    n = faces.shape[0]
    if suffix == ".ply":
        header = (
            "ply\nformat binary_little_endian 1.0\n"
            f"comment tlm scene {scene.name}: face i is triangle id i\n"
            f"element vertex {3 * n}\nproperty double x\nproperty double y\nproperty double z\n"
            f"element face {n}\nproperty list uchar int vertex_indices\n"
            "property int material\nend_header\n"
        )
        face_rec = np.zeros(n, dtype=[("k", "u1"), ("v", "<i4", 3), ("m", "<i4")])
        face_rec["k"] = 3
        face_rec["v"] = faces
        face_rec["m"] = scene.material_index
        with write_atomic(path, "wb") as f:
            f.write(header.encode())
            f.write(verts.astype("<f8").tobytes())
            f.write(face_rec.tobytes())
    else:
        lines = [f"# tlm scene {scene.name}: face i is triangle id i"]
        lines += [f"v {x!r} {y!r} {z!r}" for x, y, z in verts.tolist()]
        lines += [f"f {a + 1} {a + 2} {a + 3}" for a in range(0, 3 * n, 3)]
        write_file(path, "\n".join(lines) + "\n")
