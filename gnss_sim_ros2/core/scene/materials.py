"""Material classes of scene triangles and the rules that assign them.

A class with ``attenuation_db_per_m = None`` is opaque (blocks the line of sight); a class with a
finite value is a penetrable volume (foliage) whose loss is the path length inside times that value.
Built-in classes: ``opaque`` and ``foliage``
(:data:`~gnss_sim_ros2.core.constants.FOLIAGE_ATTENUATION_DB_PER_M`).

Assignment, first that applies wins:

1. a materials YAML file (``materials_yaml``)::

       classes:
         foliage: {attenuation_db_per_m: 1.85}
         glass: {attenuation_db_per_m: 6.0}
       rules:                      # fnmatch, case-insensitive, first match wins
         - {pattern: "*hedge*", class: foliage}
         - {pattern: "office::*window*", class: glass}
       foliage_names: [leaf, leaves, crown, ...]   # optional: replaces FOLIAGE_NAME_KEYWORDS
       opaque_names: [trunk, bark]                 # optional: replaces OPAQUE_NAME_KEYWORDS

   Patterns match the scoped name ``model[::nested]::link::collision[::mesh node]``.
2. an element in the SDF, in a custom namespace that Gazebo ignores (SDF custom elements)::

       <sdf version="1.9" xmlns:gnss_sim="urn:gnss_sim">
         ... <model name="kiosk"><gnss_sim:material>foliage</gnss_sim:material> ...

   allowed in a model, link, collision or visual (innermost wins, inherited by everything below).
   An attribute ``attenuation_db_per_m`` declares a new class on the spot.  Any namespace URI
   containing ``gnss_sim`` is accepted.
3. CONTRACT default, from names: the names of a part from the innermost out (mesh node, mesh
   geometry, mesh material and texture, SDF material script, visual/collision, link, model, the
   enclosing models) are split into words (``_``, ``-``, ``.``, ``/``, spaces, digits and
   camelCase boundaries: ``PineTree/Branch`` -> pine, tree, branch); the innermost name holding a
   word of :data:`OPAQUE_NAME_KEYWORDS` (trunk, bark...) makes the part ``opaque``, one holding a
   word of :data:`FOLIAGE_NAME_KEYWORDS` (or its plural) makes it ``foliage``; else ``opaque``.
   ``street_lamp`` is not a tree (whole words only).  Ground surfaces (``<plane>``, ``<heightmap>``)
   are opaque by default whatever their names (a "grass" field is ground, not a crown).
"""
from __future__ import annotations

import fnmatch
import math
import re
from dataclasses import dataclass, field
from pathlib import Path

from ..constants import FOLIAGE_ATTENUATION_DB_PER_M

#: CONTRACT: words of a part's names that make it foliage by default (issue 15's list)
FOLIAGE_NAME_KEYWORDS = ("leaf", "leaves", "foliage", "canopy", "crown", "branch", "tree", "bush", "hedge",
                         "grass", "plant", "vegetation", "shrub")
#: CONTRACT: words that make a part opaque by default even inside a tree (checked innermost first)
OPAQUE_NAME_KEYWORDS = ("trunk", "bark", "stem", "stump", "log")
#: namespace URI suggested for the custom material element
GNSS_SIM_SDF_NS = "urn:gnss_sim"

_CAMEL = re.compile(r"(?<=[a-z])(?=[A-Z])")
_SPLIT = re.compile(r"[^A-Za-z]+")


def name_words(name: str) -> list[str]:
    """Lower-case words of a name (rules in the module docstring)."""
    return [w.lower() for w in _SPLIT.split(_CAMEL.sub(" ", name or "")) if w]


def _has_word(words: list[str], keywords) -> bool:
    for w in words:
        for k in keywords:
            if w == k or w == k + "s" or w == k + "es":
                return True
    return False


@dataclass
class MaterialClass:
    """A material class; ``attenuation_db_per_m=None`` means opaque."""

    name: str
    attenuation_db_per_m: float | None = None

    @property
    def opaque(self) -> bool:
        return self.attenuation_db_per_m is None or not math.isfinite(self.attenuation_db_per_m)


@dataclass
class MaterialTable:
    """Material classes (index = position), name-pattern rules and the default name keywords."""

    classes: list[MaterialClass] = field(default_factory=lambda: [
        MaterialClass("opaque", None), MaterialClass("foliage", FOLIAGE_ATTENUATION_DB_PER_M)])
    rules: list[tuple[str, str]] = field(default_factory=list)  # (pattern, class name)
    foliage_names: tuple[str, ...] = FOLIAGE_NAME_KEYWORDS
    opaque_names: tuple[str, ...] = OPAQUE_NAME_KEYWORDS

    def index(self, name: str) -> int:
        for i, c in enumerate(self.classes):
            if c.name == name:
                return i
        raise KeyError(name)

    def has(self, name: str) -> bool:
        return any(c.name == name for c in self.classes)

    def declare(self, name: str, attenuation_db_per_m: float | None) -> int:
        if self.has(name):
            i = self.index(name)
            self.classes[i].attenuation_db_per_m = attenuation_db_per_m
            return i
        self.classes.append(MaterialClass(name, attenuation_db_per_m))
        return len(self.classes) - 1

    def match_rules(self, scoped_name: str) -> str | None:
        low = scoped_name.lower()
        for pattern, cls in self.rules:
            if fnmatch.fnmatchcase(low, pattern.lower()):
                return cls
        return None

    def default_for_names(self, names_innermost_first) -> int:
        """Class index from a part's names (rule 3 of the module docstring)."""
        for n in names_innermost_first:
            words = name_words(n)
            if _has_word(words, self.opaque_names):
                return self.index("opaque")
            if _has_word(words, self.foliage_names):
                return self.index("foliage")
        return self.index("opaque")

    def to_list(self) -> list[dict]:
        return [{"index": i, "name": c.name, "attenuation_db_per_m": c.attenuation_db_per_m}
                for i, c in enumerate(self.classes)]

    @classmethod
    def from_list(cls, items, where: str = "materials") -> MaterialTable:
        classes = []
        for k, item in enumerate(items):
            try:
                att = item.get("attenuation_db_per_m")
                classes.append(MaterialClass(str(item["name"]), None if att is None else float(att)))
            except (KeyError, TypeError, ValueError, AttributeError) as exc:
                raise ValueError(f"{where}[{k}]: needs name and attenuation_db_per_m (null = opaque): {exc}") from exc
        return cls(classes=classes)


def parse_attenuation(value, where: str) -> float | None:
    """``attenuation_db_per_m`` from YAML or an SDF attribute: a number >= 0, or null/opaque/inf."""
    if value is None or (isinstance(value, str) and value.strip().lower() in ("", "null", "none", "opaque", "inf")):
        return None
    try:
        v = float(value)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{where}: attenuation_db_per_m must be a number or null, got {value!r}") from exc
    if not v >= 0.0:
        raise ValueError(f"{where}: attenuation_db_per_m must be >= 0, got {v}")
    return None if math.isinf(v) else v


def _word_list(data: dict, key: str, path: Path) -> tuple[str, ...] | None:
    if key not in data:
        return None
    items = data[key]
    if not isinstance(items, list) or not all(isinstance(s, str) and s.strip() for s in items):
        raise ValueError(f"materials file {path}: {key!r} must be a list of words")
    return tuple(s.strip().lower() for s in items)


def load_materials_yaml(path) -> MaterialTable:
    """Read a materials YAML file (format in the module docstring) on top of the built-in classes."""
    import yaml

    from gnss_sim_ros2.core import yaml_file
    from gnss_sim_ros2.core.input_file import read_utf8

    path = Path(path)
    try:
        text = read_utf8(path, f"materials file {path}")
    except OSError as exc:
        raise ValueError(f"materials file {path}: cannot read: {exc}") from exc
    data = yaml_file.parse(text, yaml_file.unique_keys(yaml.SafeLoader), f"materials file {path}")
    if data is None or data == {}:     # an empty file gave the built-in table without a word
        raise ValueError(f"materials file {path} is empty: give 'classes' and/or 'rules' (or leave the option out)")
    if not isinstance(data, dict):
        raise ValueError(f"materials file {path}: top level must be a mapping with 'classes' and/or 'rules'")
    unknown = sorted(set(data) - {"classes", "rules", "foliage_names", "opaque_names"})
    if unknown:
        raise ValueError(f"materials file {path}: unknown key(s) {unknown} (classes, rules, foliage_names, "
                         f"opaque_names)")
    table = MaterialTable()
    classes = data.get("classes") or {}
    if not isinstance(classes, dict):
        raise ValueError(f"materials file {path}: 'classes' must map a class name to {{attenuation_db_per_m: ...}}")
    for name, spec in classes.items():
        where = f"materials file {path}: class {name!r}"
        if not isinstance(spec, dict) or "attenuation_db_per_m" not in spec:
            raise ValueError(f"{where}: needs attenuation_db_per_m (null = opaque)")
        table.declare(str(name), parse_attenuation(spec["attenuation_db_per_m"], where))
    rules = data.get("rules") or []
    if not isinstance(rules, list):
        raise ValueError(f"materials file {path}: 'rules' must be a list of {{pattern, class}}")
    for k, rule in enumerate(rules):
        if not isinstance(rule, dict) or "pattern" not in rule or "class" not in rule:
            raise ValueError(f"materials file {path}: rules[{k}] needs 'pattern' and 'class'")
        if not table.has(str(rule["class"])):
            raise ValueError(f"materials file {path}: rules[{k}] names unknown class {rule['class']!r} "
                             f"(declare it under 'classes')")
        table.rules.append((str(rule["pattern"]), str(rule["class"])))
    fol = _word_list(data, "foliage_names", path)
    opq = _word_list(data, "opaque_names", path)
    if fol is not None:
        table.foliage_names = fol
    if opq is not None:
        table.opaque_names = opq
    return table
