"""The one strict YAML reading of the project's input files (parameter files, receiver profiles, scenarios).

PyYAML keeps the last of two equal keys of a mapping without a word (``duration_s: 10`` then ``duration_s: 20``
reads 20; two sections of one node: only the second); YAML 1.2 requires keys to be unique
(https://yaml.org/spec/1.2.2/#mapping, "the content of a mapping node is an unordered set of key/value node
pairs, with the restriction that each of the keys is unique").  :func:`unique_keys` refuses them naming both lines.
PyYAML (YAML 1.1) also reads ``1e9`` and ``1.5e3`` (an exponent without a dot or without a sign) as text
("must be double, got '1e9'") where ROS 2's parameter parser (rcl_yaml_param_parser: strtod) and YAML 1.2's core
schema (https://yaml.org/spec/1.2.2/#1032-tag-resolution) read a number: the loader reads them as numbers too
(:data:`EXPONENT_FLOAT`), so a file means here what it means to the nodes.
"""
from __future__ import annotations

import functools
import re

MERGE_TAG = "tag:yaml.org,2002:merge"
#: YAML 1.2 floats with an exponent that YAML 1.1 reads as text (no dot or no exponent sign: 1e9, 1.5e3, .5E2)
EXPONENT_FLOAT = re.compile(r"^[-+]?(\.[0-9]+|[0-9][0-9_]*(\.[0-9_]*)?)[eE][-+]?[0-9]+$")


@functools.cache
def unique_keys(base):
    """The loader class ``base`` (a PyYAML loader) refusing a key given twice in one mapping: a
    ``yaml.constructor.ConstructorError`` marking the second key (``<<`` merges may still be overridden)."""
    import yaml

    class Loader(base):
        def construct_mapping(self, node, deep=False):
            if isinstance(node, yaml.MappingNode):
                first_line: dict = {}
                for key_node, _ in node.value:
                    if key_node.tag == MERGE_TAG or not isinstance(key_node, yaml.ScalarNode):
                        continue
                    key = self.construct_object(key_node)
                    if key in first_line:
                        raise yaml.constructor.ConstructorError(
                            "while reading a mapping", node.start_mark,
                            f"found the key {key!r} twice (first on line {first_line[key]})", key_node.start_mark)
                    first_line[key] = key_node.start_mark.line + 1
            return super().construct_mapping(node, deep=deep)

    Loader.add_implicit_resolver("tag:yaml.org,2002:float", EXPONENT_FLOAT, list("-+.0123456789"))
    Loader.__name__ = f"Unique{base.__name__}"
    return Loader


def parse(text: str, loader, where: str, error: type[ValueError] = ValueError, with_nodes: bool = False):
    """``yaml.load(text, loader)`` (with ``with_nodes``: and the node tree with line marks, ``yaml.compose``);
    ``error`` (ValueError or a subclass) naming ``where`` for text that is not YAML or nests so deeply that the
    parser's recursion gives up (PyYAML is recursive: about 1000 levels)."""
    import yaml

    try:
        doc = yaml.load(text, Loader=loader)
        return (doc, yaml.compose(text, Loader=loader)) if with_nodes else doc
    except yaml.YAMLError as exc:
        raise error(f"{where}: not valid YAML: {exc}") from None
    except RecursionError:
        raise error(f"{where}: not valid YAML: nested too deeply") from None
