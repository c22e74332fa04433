"""STL mesh files read with NumPy alone (the collision meshes of most robot descriptions).

Binary STL: an 80-byte header, a little-endian ``uint32`` triangle count ``n``, then ``n``
records of 50 bytes (normal and three vertices as 12 ``float32``, a 2-byte attribute); a file
is binary when its size is exactly ``84 + 50 n`` (an ASCII file's header may also start with
``solid``). ASCII STL: ``facet ... outer loop vertex x y z (x3) endloop endfacet`` blocks, read
from the ``vertex`` lines. The stored normals are ignored (the orientation is the vertex
order). Vertices at the same coordinates become one.
"""

from __future__ import annotations

import numpy as np

__all__ = ["read_stl"]


def read_stl(data: bytes) -> tuple[np.ndarray, np.ndarray]:
    """``(vertices (v, 3) float64, faces (f, 3) int64)`` of an STL file's bytes; a
    ``ValueError`` when they are neither binary nor ASCII STL."""
    if len(data) >= 84:
        count = int(np.frombuffer(data, dtype="<u4", count=1, offset=80)[0])
        if len(data) == 84 + 50 * count:
            record = np.dtype([("normal", "<f4", 3), ("vertices", "<f4", (3, 3)), ("attr", "<u2")])
            triangles = np.frombuffer(data, dtype=record, count=count, offset=84)["vertices"]
            return _indexed(triangles.astype(np.float64))
    try:
        text = data.decode("ascii")
    except UnicodeDecodeError:
        raise ValueError("not an STL file (neither binary nor ASCII STL)") from None
    if not text.lstrip().lower().startswith("solid"):
        raise ValueError("not an STL file (neither binary nor ASCII STL)")
    words = text.split()
    at = [i for i, word in enumerate(words) if word.lower() == "vertex"]
    try:
        points = np.array([[float(w) for w in words[i + 1 : i + 4]] for i in at])
    except ValueError:
        raise ValueError("an ASCII STL vertex is not three numbers") from None
    if len(points) % 3:
        raise ValueError(f"an ASCII STL with {len(points)} vertices, not three per facet")
    return _indexed(points.reshape(-1, 3, 3))


def _indexed(triangles: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Triangles ``(f, 3, 3)`` as shared vertices and faces."""
    if len(triangles) == 0:
        return np.zeros((0, 3)), np.zeros((0, 3), np.int64)
    vertices, index = np.unique(triangles.reshape(-1, 3), axis=0, return_inverse=True)
    return vertices, index.reshape(-1, 3).astype(np.int64)
