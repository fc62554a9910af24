"""docs/ARCHITECTURE.md stays true to the code: every path it names exists, every package (and every module at
the top of gnss_sim_ros2/) is named, its core layers and import contracts are those of .importlinter."""
from __future__ import annotations

import configparser
import re
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
PKG = REPO / "gnss_sim_ros2"
DOC = REPO / "docs" / "ARCHITECTURE.md"
CONTRACT = REPO / ".importlinter"

_FENCE = re.compile(r"^```.*?^```", flags=re.M | re.S)
_SPAN = re.compile(r"`([^`\n]+)`")
#: a relative path: words of letters, digits, '.', '_', '-' joined by '/', a final '/' for a folder
_PATH = re.compile(r"[\w.-]+(?:/[\w.-]+)*/?")


def _is_path(token: str) -> bool:
    return bool(_PATH.fullmatch(token)) and ("/" in token or token.endswith((".py", ".md")))


def named_paths(text: str) -> list[str]:
    """The paths ``text`` names: code spans that are a path (``core/time.py``, ``gnss_sim_ros2/messages/``),
    and the path-like words of its fenced blocks (the pictures: ``(core/ephemeris/)``). Topics (``/tf``) are
    not paths."""
    fences = _FENCE.findall(text)
    spans = [s.strip() for s in _SPAN.findall(_FENCE.sub("", text))]
    words = [w.strip("()[],;:") for block in fences for w in block.split()]
    # in a picture only a word that reads as a file or folder (not "C/N0" or an arrow's "----/tf")
    words = [w for w in words if w[:1].isalpha() and w.endswith((".py", ".md", "/"))]
    return [t for t in spans + words if _is_path(t)]


def resolve(name: str) -> Path | None:
    """The file or folder ``name`` means: under gnss_sim_ros2/, else under the repository; None if neither
    (a name ending in '/' must be a folder)."""
    for root in (PKG, REPO):
        p = root / name
        if p.exists() and (p.is_dir() or not name.endswith("/")):
            return p.resolve()
    return None


def table_rows(text: str, heading: str) -> list[list[str]]:
    """The cells of the Markdown table under ``heading`` (header and rule rows left out)."""
    section = text.split(heading, 1)[1]
    section = re.split(r"^#{1,6} ", section, maxsplit=1, flags=re.M)[0]
    rows = [line.strip().strip("|").split("|") for line in section.splitlines() if line.startswith("|")]
    return [[c.strip() for c in r] for r in rows[2:]]


def doc_layers(text: str) -> list[set[str]]:
    """The core layers of the page, top to bottom: each a set of module names (``core/rtk/`` -> ``rtk``)."""
    layers = []
    for row in table_rows(text, "### The core's layers"):
        names = _SPAN.findall(row[1])
        layers.append({re.sub(r"\.py$", "", n.removeprefix("core/").rstrip("/")) for n in names})
    return layers


def contract() -> configparser.ConfigParser:
    cfg = configparser.ConfigParser()
    cfg.read(CONTRACT, encoding="utf-8")
    return cfg


def contract_layers(cfg: configparser.ConfigParser) -> list[set[str]]:
    lines = [line for line in cfg["importlinter:contract:core-layers"]["layers"].splitlines() if line.strip()]
    return [{m.strip() for m in line.split("|")} for line in lines]


def contract_ids(cfg: configparser.ConfigParser) -> set[str]:
    return {s.removeprefix("importlinter:contract:") for s in cfg.sections() if s.startswith("importlinter:contract:")}


def _text() -> str:
    return DOC.read_text(encoding="utf-8")


def test_the_parser_finds_paths_in_spans_and_pictures():
    text = ("`core/time.py` and `commands/run/` and `/gnss/fix` and `tf_tree.FrameWait` and `bench/*.py`\n"
            "```\n a -> b   (core/nowhere.py)  /tf, /tf_static ---/tf C/N0\n```\n")
    assert named_paths(text) == ["core/time.py", "commands/run/", "core/nowhere.py"]
    assert resolve("core/time.py") == (PKG / "core" / "time.py").resolve()
    assert resolve("test/test_architecture_doc.py") is not None
    assert resolve("core/nowhere.py") is None
    assert resolve("core/time.py/") is None          # a file named as a folder


def test_every_named_path_exists():
    missing = sorted({p for p in named_paths(_text()) if resolve(p) is None})
    assert not missing, f"docs/ARCHITECTURE.md names paths that do not exist: {missing}"


def test_every_package_and_top_module_is_named():
    named = {resolve(p) for p in named_paths(_text())} - {None}
    packages = sorted(p.parent for p in PKG.rglob("__init__.py") if "__pycache__" not in p.parts)
    top_modules = sorted(p for p in PKG.glob("*.py") if p.name != "__init__.py")
    unnamed = [str(p.relative_to(REPO)) for p in packages + top_modules if p.resolve() not in named]
    assert not unnamed, f"docs/ARCHITECTURE.md does not name: {unnamed}"


def test_the_core_layers_are_those_of_the_contract():
    doc, lint = doc_layers(_text()), contract_layers(contract())
    assert doc == lint, f"docs/ARCHITECTURE.md layers (top to bottom)\n{doc}\n.importlinter core-layers\n{lint}"


def test_the_contracts_are_those_of_the_contract_file():
    doc = {_SPAN.findall(row[0])[0] for row in table_rows(_text(), "### The import contracts")}
    assert doc == contract_ids(contract())
