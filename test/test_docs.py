"""The documentation stays true: the README short, every relative link resolving, the configuration reference
equal to what its generator writes from the parameter table (``gnss-sim config --markdown``)."""
from __future__ import annotations

import re
from pathlib import Path

import pytest

from gnss_sim_ros2.commands.config import REFERENCE_PATH, config_reference_markdown

REPO_ROOT = Path(__file__).resolve().parents[1]
README = REPO_ROOT / "README.md"
DOCS = sorted((REPO_ROOT / "docs").glob("*.md"))
#: the README is for a newcomer: what it is, the two commands, the tour, the ROS quick start, links
README_MAX_LINES = 300

#: [text](target) and ![alt](target), target without spaces, an optional "title" after it
_LINK = re.compile(r"!?\[[^\]]*\]\(\s*<?([^)\s>]+)>?(?:\s+\"[^\"]*\")?\s*\)")
_FENCE = re.compile(r"^```.*?^```", flags=re.M | re.S)
_CODE_SPAN = re.compile(r"`[^`\n]*`")


def links_of(text: str) -> list[str]:
    """The link targets of Markdown ``text``, outside fenced blocks and code spans."""
    text = _CODE_SPAN.sub("", _FENCE.sub("", text))
    return _LINK.findall(text)


def heading_anchors(text: str) -> set[str]:
    """GitHub's anchors of the headings of ``text``: lower case, punctuation dropped, spaces as hyphens."""
    anchors = set()
    for heading in re.findall(r"^#{1,6}\s+(.*?)\s*#*\s*$", _FENCE.sub("", text), flags=re.M):
        slug = re.sub(r"[^\w\- ]", "", heading.lower()).replace(" ", "-")
        anchors.add(slug)
    return anchors


def broken_links(page: Path) -> list[str]:
    """The relative links of ``page`` whose file (or heading anchor in a Markdown file) does not exist."""
    broken = []
    text = page.read_text(encoding="utf-8")
    for target in links_of(text):
        if re.match(r"^[a-z][a-z0-9+.-]*:", target):        # http:, https:, mailto:
            continue
        path, _, anchor = target.partition("#")
        dest = (page.parent / path).resolve() if path else page
        if not dest.exists():
            broken.append(f"{target}: no file {dest}")
        elif anchor and dest.suffix == ".md" and anchor not in heading_anchors(dest.read_text(encoding="utf-8")):
            broken.append(f"{target}: no heading '#{anchor}' in {dest.name}")
    return broken


def test_the_link_parser_sees_links_and_skips_code():
    text = "see [a](docs/A.md#x), ![p](img.png) and `[not](here.md)`\n```\n[nor](there.md)\n```\n"
    assert links_of(text) == ["docs/A.md#x", "img.png"]
    assert heading_anchors("# One `two`: three\n## Many robots (`run --robots N`)\n") == {
        "one-two-three", "many-robots-run---robots-n"}


@pytest.mark.parametrize("page", [README, *DOCS], ids=lambda p: str(p.relative_to(REPO_ROOT)))
def test_relative_links_resolve(page):
    assert not broken_links(page), f"{page.relative_to(REPO_ROOT)}: broken links\n" + "\n".join(broken_links(page))


def test_a_missing_target_is_reported(tmp_path):
    page = tmp_path / "page.md"
    (tmp_path / "there.md").write_text("# Here\n", encoding="utf-8")
    page.write_text("[a](there.md#here) [b](gone.md) [c](there.md#elsewhere) [d](https://example.org)\n",
                    encoding="utf-8")
    assert [b.split(":")[0] for b in broken_links(page)] == ["gone.md", "there.md#elsewhere"]


def test_readme_is_short():
    lines = README.read_text(encoding="utf-8").count("\n")
    assert lines < README_MAX_LINES, f"README.md has {lines} lines; the details belong in docs/"


def test_configuration_reference_is_generated_from_the_parameter_table():
    """docs/CONFIGURATION.md is what `gnss-sim config --markdown` writes: regenerate it after a table change."""
    committed = (REPO_ROOT / REFERENCE_PATH).read_text(encoding="utf-8")
    assert committed == config_reference_markdown(), (
        f"{REFERENCE_PATH} differs from the parameter table: run "
        f"`.venv/bin/gnss-sim config --markdown > {REFERENCE_PATH}`")


def test_configuration_reference_names_every_parameter():
    from gnss_sim_ros2.parameters import NODE_NAMES, NODE_PARAMS, SHARED

    text = config_reference_markdown()
    for p in SHARED + [p for params in NODE_PARAMS.values() for p in params]:
        assert f"| `{p.name}` |" in text, p.name
    for name in NODE_NAMES.values():
        assert f"## `{name}`" in text, name
