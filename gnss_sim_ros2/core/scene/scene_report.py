"""What a world load kept, skipped and why: printed by ``export-world`` and kept in the sidecar.

* ``skipped``: parts that could not be loaded (a mesh not found, a Fuel model not in the cache, an
  unsupported geometry or raster): the scene would lack geometry the world names.  With ``strict`` (the
  default of every front end: parameter ``strict_world``) the load ends in one :class:`PartialWorldError`
  naming the world, the first such part and why, and how many more; a partial world
  (``--allow-partial``, ``strict_world: false``) keeps the rest with one warning (:class:`SceneWarning`)
  per part.
* ``left_out``: what is left out by design and is not an error: geometry-free includes (lights),
  non-static models and actors (they move; ``keep_dynamic`` keeps non-static models) and roads (flat).
* ``dropped``: mesh files some of whose triangles could not be cast against (NaN vertex, zero area), dropped
  (:mod:`.mesh_files`); the rest of the file is kept.
"""
from __future__ import annotations

import warnings
from dataclasses import dataclass, field

from .sdf_xml import SdfError


class SceneWarning(UserWarning):
    """A part of a world was skipped (the message names it and why)."""


class LeftOutWarning(UserWarning):
    """Non-static models were left out of a world (one warning a load, naming them)."""


class PartialWorldError(SdfError):
    """A strict load lost geometry the world names (the message names the world, the part and why)."""


#: how a user asks for a partial world, in every error that refuses one
PARTIAL_ADVICE = "--allow-partial (parameter strict_world: false) loads the rest"
#: help of the --allow-partial option of every command that loads a world (export-world, skyplot, simulate, run)
ALLOW_PARTIAL_HELP = ("load what can be loaded of the world: a part that cannot (a model:// or mesh not found, an "
                      "uncached Fuel model) is skipped with a warning instead of an error (parameter strict_world: "
                      "false)")


@dataclass
class SceneReport:
    strict: bool = False
    skipped: list[dict] = field(default_factory=list)     # {part, reason}
    left_out: list[dict] = field(default_factory=list)    # {part, reason}
    dropped: list[dict] = field(default_factory=list)     # {file, triangles, of, ...} (mesh_files.drop_bad_triangles)
    parts_loaded: int = 0
    mesh_files_read: int = 0
    mesh_cache_hits: int = 0

    def skip(self, part: str, reason: str) -> None:
        """Record a part that cannot be loaded: one warning (a partial world), or kept for the error of
        :meth:`raise_if_partial` when strict."""
        self.skipped.append({"part": part, "reason": reason})
        if not self.strict:
            warnings.warn(f"skipped {part}: {reason}", SceneWarning, stacklevel=3)

    def skip_error(self, part: str, exc: SdfError) -> None:
        """:meth:`skip` for an error raised while loading ``part``."""
        self.skip(part, str(exc))

    def raise_if_partial(self, source: str) -> None:
        """With ``strict``: one :class:`PartialWorldError` when a part was skipped (the first named, the others
        counted)."""
        if not self.strict or not self.skipped:
            return
        first, others = self.skipped[0], [it["part"] for it in self.skipped[1:]]
        more = ""
        if others:
            more = f"; also cannot load {', '.join(others[:3])}" + (
                f" and {len(others) - 3} more" if len(others) > 3 else "")
        raise PartialWorldError(f"world {source}: cannot load {first['part']}: {first['reason']}{more}; the scene "
                                f"would lack geometry the world names: {PARTIAL_ADVICE}")

    def leave_out(self, part: str, reason: str) -> None:
        self.left_out.append({"part": part, "reason": reason})

    def warn_left_out_dynamic(self) -> None:
        """One warning naming the non-static models left out (a user of simulate sees no report)."""
        names = [it["part"] for it in self.left_out if it["reason"].startswith("not static")]
        if names:
            shown = ", ".join(names[:8]) + (f" and {len(names) - 8} more" if len(names) > 8 else "")
            warnings.warn(f"left out {len(names)} non-static model(s) ({shown}): they move in Gazebo; "
                          f"keep_dynamic (export-world --keep-dynamic) keeps them", LeftOutWarning, stacklevel=3)

    def to_dict(self, triangles: dict[str, int]) -> dict:
        return {"parts_loaded": self.parts_loaded, "triangles": dict(triangles),
                "skipped": list(self.skipped), "left_out": list(self.left_out), "dropped": list(self.dropped),
                "mesh_files_read": self.mesh_files_read, "mesh_cache_hits": self.mesh_cache_hits}


def report_lines(report: dict, limit: int = 20) -> list[str]:
    """Human-readable summary of a report dict (``WorldMesh.report``)."""
    tri = report.get("triangles", {})
    lines = [f"scene report: {report.get('parts_loaded', 0)} parts loaded, "
             + ", ".join(f"{k} {v} triangles" for k, v in tri.items())
             + f"; {report.get('mesh_files_read', 0)} mesh files read ({report.get('mesh_cache_hits', 0)} reuses)"]
    for key, title in (("skipped", "skipped"), ("left_out", "left out")):
        items = report.get(key) or []
        if items:
            lines.append(f"  {title}: {len(items)}")
            for it in items[:limit]:
                lines.append(f"    {it['part']}: {it['reason']}")
            if len(items) > limit:
                lines.append(f"    ... {len(items) - limit} more (see the sidecar)")
    for it in report.get("dropped") or []:
        lines.append(f"  dropped {it['triangles']} of {it['of']} triangles of {it['file']} (NaN/infinite vertex "
                     f"{it['non_finite']}, bad index {it['bad_index']}, zero area {it['degenerate']})")
    return lines
