"""``<population>`` (SDF 1.5+, Gazebo Classic ``Population``): copies of one model in a region.

The region is ``<box><size>`` (centred on the population pose) or ``<cylinder>`` (``<radius>``,
``<length>``, axis z, centred); ``<model_count>`` copies; ``<distribution><type>``:

* ``random``: uniform over the region;
* ``uniform``: evenly spread (k-means centres of many uniform samples, as Gazebo Classic does);
* ``grid``: ``<rows>`` x ``<cols>`` copies ``<step>`` apart, starting at the population pose and
  going along +x (columns) and +y (rows), as Gazebo Classic's ``CreatePosesGrid``;
* ``linear-x`` / ``linear-y`` / ``linear-z``: evenly along that axis of the region, centred.

Gazebo draws the random positions from an unseeded generator; here the generator is seeded (``seed``
of the load plus the population name), so a world exports the same every time.  Positions are in the
population frame, which its ``<pose>`` places in the world; each copy keeps its model's own rotation.
"""
from __future__ import annotations

import zlib

import numpy as np

from .sdf_xml import SdfError, child, child_floats, text, where

DISTRIBUTIONS = ("random", "uniform", "grid", "linear-x", "linear-y", "linear-z")


def _region(pop_el, file):
    box = child(pop_el, "box")
    cyl = child(pop_el, "cylinder")
    if box is not None:
        return "box", child_floats(box, "size", file, 3)
    if cyl is not None:
        (r,) = child_floats(cyl, "radius", file, 1)
        (ln,) = child_floats(cyl, "length", file, 1)
        return "cylinder", [r, ln]
    return None, None


def _uniform_in(kind, dims, n, rng) -> np.ndarray:
    if kind == "box":
        return (rng.random((n, 3)) - 0.5) * np.asarray(dims)
    r, ln = dims
    rho = r * np.sqrt(rng.random(n))
    phi = rng.random(n) * 2 * np.pi
    return np.c_[rho * np.cos(phi), rho * np.sin(phi), (rng.random(n) - 0.5) * ln]


def population_offsets(pop_el, file, seed: int = 0) -> np.ndarray:
    """(N, 3) positions of the copies in the population frame."""
    dist_el = child(pop_el, "distribution")
    kind_el = child(dist_el, "type") if dist_el is not None else None
    dist = text(kind_el, "random").lower() if kind_el is not None else "random"
    if dist not in DISTRIBUTIONS:
        raise SdfError(f"{where(kind_el, file)}: unknown population distribution {dist!r} "
                       f"(one of {', '.join(DISTRIBUTIONS)})")
    name = pop_el.get("name") or ""
    rng = np.random.default_rng([seed, zlib.crc32(name.encode())])
    if dist == "grid":
        rows = int(child_floats(dist_el, "rows", file, 1, default=(1,))[0])
        cols = int(child_floats(dist_el, "cols", file, 1, default=(1,))[0])
        step = child_floats(dist_el, "step", file, 3, default=(0.5, 0.5, 0))
        if rows < 1 or cols < 1:
            raise SdfError(f"{where(dist_el, file)}: grid needs rows >= 1 and cols >= 1")
        r, c = np.meshgrid(np.arange(rows), np.arange(cols), indexing="ij")
        return np.c_[c.ravel() * step[0], r.ravel() * step[1], np.zeros(rows * cols)]
    count_el = child(pop_el, "model_count")
    n = int(child_floats(pop_el, "model_count", file, 1)[0]) if count_el is not None else 1
    if n < 1:
        raise SdfError(f"{where(count_el, file)}: model_count must be >= 1, got {n}")
    kind, dims = _region(pop_el, file)
    if kind is None:
        raise SdfError(f"{where(pop_el, file)}: a {dist} population needs a <box> or <cylinder> region")
    if dist == "random":
        return _uniform_in(kind, dims, n, rng)
    if dist == "uniform":
        from scipy.cluster.vq import kmeans2

        samples = _uniform_in(kind, dims, max(50 * n, 200), rng)
        centres, _ = kmeans2(samples, n, minit="++", seed=rng)
        return centres
    axis = "xyz".index(dist[-1])
    extent = dims[axis] if kind == "box" else (2 * dims[0] if axis < 2 else dims[1])
    out = np.zeros((n, 3))
    out[:, axis] = (np.arange(n) + 0.5) / n * extent - extent / 2.0
    return out
