"""What a world load kept, skipped and why: printed by ``export-world`` and kept in the sidecar.

* ``skipped``: parts that could not be loaded (a mesh not found, a Fuel model not in the cache, an
  unsupported geometry or raster): each one warning (:class:`SceneWarning`) naming the part and the
  reason; with ``strict`` each is an :class:`~.sdf_xml.SdfError` instead.
* ``left_out``: what is left out by design and is not an error: geometry-free includes (lights),
  non-static models and actors (they move; ``keep_dynamic`` keeps non-static models) and roads (flat).
"""
from __future__ import annotations

import warnings
from dataclasses import dataclass, field

from .sdf_xml import SdfError


class SceneWarning(UserWarning):
    """A part of a world was skipped (the message names it and why)."""


class LeftOutWarning(UserWarning):
    """Non-static models were left out of a world (one warning a load, naming them)."""


class StrictSkipError(SdfError):
    """A part that cannot be loaded, with ``strict``: passed up unchanged by the enclosing parts."""


@dataclass
class SceneReport:
    strict: bool = False
    skipped: list[dict] = field(default_factory=list)     # {part, reason}
    left_out: list[dict] = field(default_factory=list)    # {part, reason}
    parts_loaded: int = 0
    mesh_files_read: int = 0
    mesh_cache_hits: int = 0

    def skip(self, part: str, reason: str) -> None:
        """Record a part that cannot be loaded: one warning, or an error when strict."""
        if self.strict:
            raise StrictSkipError(f"{part}: {reason} (--strict: a part that cannot be loaded is an error)")
        self.skipped.append({"part": part, "reason": reason})
        warnings.warn(f"skipped {part}: {reason}", SceneWarning, stacklevel=3)

    def skip_error(self, part: str, exc: SdfError) -> None:
        """:meth:`skip` for an error raised while loading ``part`` (a strict error of an inner part goes on up)."""
        if isinstance(exc, StrictSkipError):
            raise exc
        self.skip(part, str(exc))

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
                "skipped": list(self.skipped), "left_out": list(self.left_out),
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
    return lines
